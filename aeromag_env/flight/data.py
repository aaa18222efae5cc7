"""The in-memory flight: named 1-D channels of equal length, in the flat MagNav/SGL layout.

Field names follow the SGL 2020 data set (DESIGN.md, "Data files"), so real files load as is:

============================== ====== ==================================================
field                          unit   meaning
============================== ====== ==================================================
``tt``                         s      time, strictly increasing
``lat``, ``lon``               deg    position
``alt`` (or ``utm_z``,         m      altitude
``ins_alt``)
``year``, ``doy``              –      date for the Earth-field model (or attribute ``date``)
``ins_roll/pitch/yaw``         deg    attitude (aerospace ZYX, see :mod:`aeromag_env.units`)
``flux_a_x/y/z``               nT     vector magnetometer ``a`` in body axes (``flux_b``…)
``mag_1_uc``                   nT     uncompensated scalar magnetometer 1 (``mag_2_uc``…)
``diurnal``                    nT     base-station variation
``cur_*``, ``vol_*``,          A, V,  auxiliary channels
``temp_*``                     °C
``line``                       –      flight line id
``maneuver``                   –      0 outside, 1–12 inside the calibration maneuvers
``truth_*``                    nT     simulator ground truth (simulated files only)
============================== ====== ==================================================

Degrees are converted to radians by the accessors here; nothing else in the package sees them.
"""

from __future__ import annotations

import datetime as _dt
import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from aeromag_env.geo.earth import check_model_date, parse_date

ALTITUDE_NAMES = ("alt", "utm_z", "ins_alt")
ATTITUDE_NAMES = ("ins_roll", "ins_pitch", "ins_yaw")
POSITION_NAMES = ("lat", "lon")
#: The largest manoeuvre window id read [-]: a box has 12, a file a few boxes; a label beyond it
#: (a corrupt byte: 2**33), negative or fractional is not a window id and reads as 0.
MAX_MANEUVER_ID = 10_000
AUX_PREFIXES = ("cur_", "vol_", "temp_")
AXES = ("x", "y", "z")

_FLUX_RE = re.compile(r"^(flux_[a-z])_x$")
_SCALAR_RE = re.compile(r"^mag_\d+_uc$")


def vector_names(prefix: str) -> tuple[str, str, str]:
    """``"flux_a"`` → ``("flux_a_x", "flux_a_y", "flux_a_z")``."""
    return tuple(f"{prefix}_{a}" for a in AXES)  # type: ignore[return-value]


@dataclass
class Flight:
    """Named channels of one flight.

    Attributes
    ----------
    fields : dict[str, ndarray]
        Channel name → 1-D float array; all of the same length ``n``.
    attrs : dict[str, Any]
        File attributes: ``date`` (ISO), ``config`` (JSON of the generating configuration, simulated
        files), ``truth_coefficients`` (JSON), ``source``…
    """

    fields: dict[str, np.ndarray]
    attrs: dict[str, Any] = field(default_factory=dict)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.fields[name]

    def __contains__(self, name: object) -> bool:
        return name in self.fields

    @property
    def names(self) -> list[str]:
        """Channel names in file order."""
        return list(self.fields)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(next(iter(self.fields.values())).size) if self.fields else 0

    @property
    def tt(self) -> np.ndarray:
        """Time [s], shape (n,)."""
        return self.fields["tt"]

    @property
    def duration_s(self) -> float:
        """Last minus first time [s]."""
        return float(self.tt[-1] - self.tt[0]) if self.n > 1 else 0.0

    @property
    def sample_rate_hz(self) -> float:
        """Median sample rate [Hz]."""
        return float(1.0 / np.median(np.diff(self.tt))) if self.n > 1 else float("nan")

    def vector(self, prefix: str) -> np.ndarray:
        """Vector channel ``prefix_x/y/z``, shape (n, 3), e.g. ``"flux_a"``, ``"truth_earth"``."""
        return np.column_stack([self.fields[nm] for nm in vector_names(prefix)])

    def fluxgates(self) -> list[str]:
        """Fluxgate ids present with all three axes, e.g. ``["flux_a", "flux_b"]``."""
        ids = (m.group(1) for nm in self.fields if (m := _FLUX_RE.match(nm)))
        return sorted(i for i in ids if all(nm in self.fields for nm in vector_names(i)))

    def scalars(self) -> list[str]:
        """Uncompensated scalar magnetometer channels present, e.g. ``["mag_1_uc"]``."""
        return sorted(nm for nm in self.fields if _SCALAR_RE.match(nm))

    def aux_channels(self) -> list[str]:
        """Auxiliary channels (``cur_*``, ``vol_*``, ``temp_*``) present."""
        return [nm for nm in self.fields if nm.startswith(AUX_PREFIXES)]

    def altitude_name(self) -> str | None:
        """The altitude channel used: the first of ``alt``, ``utm_z``, ``ins_alt`` present."""
        return next((nm for nm in ALTITUDE_NAMES if nm in self.fields), None)

    def attitude_rad(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Roll, pitch, yaw [rad], each shape (n,)."""
        roll, pitch, yaw = (np.deg2rad(self.fields[nm]) for nm in ATTITUDE_NAMES)
        return roll, pitch, yaw

    def position_rad(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Latitude [rad], longitude [rad], altitude [m], each shape (n,)."""
        alt = self.altitude_name()
        if alt is None:
            raise KeyError("no altitude channel (alt, utm_z or ins_alt)")
        lat, lon = (np.deg2rad(self.fields[nm]) for nm in POSITION_NAMES)
        return lat, lon, self.fields[alt]

    def date(self) -> _dt.datetime:
        """Epoch for the Earth-field model: attribute ``date``, else the first ``year``/``doy``.

        Raises KeyError without either; ValueError (or OverflowError) for a date that cannot be
        read (not ISO 8601, a non-finite year or doy) and
        :class:`~aeromag_env.geo.earth.ModelDateError` for one outside IGRF-14's years, each
        naming the field and its value.
        """
        if "date" in self.attrs:
            value = self.attrs["date"]
            return check_model_date(parse_date(value), f"date attribute {str(value)!r}")
        if "year" in self.fields and "doy" in self.fields:
            year, doy = float(self.fields["year"][0]), float(self.fields["doy"][0])
            source = f"year {year:g}, doy {doy:g} at the first sample"
            try:
                date = _dt.datetime(int(year), 1, 1) + _dt.timedelta(days=doy - 1.0)
            except (ValueError, OverflowError) as exc:  # NaN, inf, a year beyond 1…9999
                raise ValueError(f"{source}: not a date ({exc})") from None
            return check_model_date(date, source)
        raise KeyError("no date: neither a 'date' attribute nor 'year' and 'doy' fields")

    def maneuver_windows(self) -> list[tuple[int, float, float]]:
        """Maneuver windows ``(id, t_start, t_end)`` [s], from the ``maneuver`` field."""
        if "maneuver" not in self.fields:
            return []
        m = self.maneuver_ids()
        out = []
        for mid in np.unique(m[m > 0]):
            k = np.flatnonzero(m == mid)
            out.append((int(mid), float(self.tt[k[0]]), float(self.tt[k[-1]])))
        return out

    def maneuver_ids(self) -> np.ndarray:
        """(n,) int window ids from the ``maneuver`` field (zeros without one); a label that is
        not a whole number in 0…:data:`MAX_MANEUVER_ID` (NaN, a corrupt value) reads as 0."""
        m = self.fields.get("maneuver", np.zeros(self.n))
        return np.where(self.bad_maneuver_labels() | ~np.isfinite(m), 0, m).astype(int)

    def bad_maneuver_labels(self) -> np.ndarray:
        """(n,) True where a finite ``maneuver`` label is not a window id (see
        :meth:`maneuver_ids`); NaN is a missing label, not a bad one."""
        m = self.fields.get("maneuver", np.zeros(self.n))
        finite = np.isfinite(m)
        return finite & ((m < 0) | (m > MAX_MANEUVER_ID) | (m != np.round(m)))
