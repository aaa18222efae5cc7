"""Checks on a flight read from a file: structure, required fields, time, units, non-finite samples.

Fatal problems raise :class:`~aeromag_env.errors.FlightFileError` with a one-line message that names
the file, the field(s) and the problem; everything else is returned as a list of warnings:

* Always fatal: no fields, zero samples, fields of different lengths, a missing required field,
  a ``tt`` that is non-finite or not strictly increasing.
* Implausible units (a field magnitude in µT, gauss or tesla instead of nT, one far beyond the
  Earth's field, attitude in radians, latitude beyond ±90°, an unreadable date) are fatal when
  the caller needs the channel (``needs``), and a warning otherwise: a method never computes
  with a wrong unit, and a file is not refused for a channel the method does not use.
* Non-finite samples are never fatal: :func:`nonfinite_report` says how many and where, and the
  caller decides (and says) what to do with them.
"""

from __future__ import annotations

import os
import re
from collections import Counter
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from aeromag_env.errors import FlightFileError
from aeromag_env.flight.data import ATTITUDE_NAMES, POSITION_NAMES, Flight, vector_names
from aeromag_env.flight.quality import fault_problems, fault_report
from aeromag_env.geo.earth import ModelDateError, igrf_ned
from aeromag_env.geo.frames import dcm_from_euler, nav_to_body
from aeromag_env.units import EARTH_FIELD_RANGE_NT, WGS84_A_M

#: A field magnitude above this is not a field in nT [nT].
IMPLAUSIBLE_FIELD_NT = 200_000.0

#: Median magnitude bands that mean another unit: (low, high, unit, factor to nT).
_UNIT_BANDS = ((10.0, 100.0, "µT", "1000"), (0.1, 1.0, "gauss", "1e5"), (1e-5, 1e-4, "T", "1e9"))

_MAX_LISTED = 20
_MAX_POINTS = 200  # subsample for the physics check of the attitude unit
_TWO_PI_TOL = 2.0 * np.pi + 0.01  # [rad]; a file storing exactly 2π is still ambiguous
_YAW_SPAN_RAD = 3.0  # a yaw span above this within ±2π is a turn in radians [rad]
_MAX_YAW_RATE_RAD_S = 0.35  # 20°/s: faster than any survey turn [rad/s]
_MARGIN_RAD = np.deg2rad(5.0)  # how much better one unit hypothesis must fit [rad]
_UNIT_SCALES = (("degrees", np.pi / 180.0), ("radians", 1.0))  # attitude hypotheses → rad
_RADIANS_MSG = "ins_roll/ins_pitch/ins_yaw look like radians; expected degrees (multiply by 180/π)"
_VECTOR_RE = re.compile(r"^flux_[a-z]$")

PathLike = str | os.PathLike[str]
#: (fields involved, fatal if the caller needs one of them, message)
Problem = tuple[tuple[str, ...], bool, str]


class FlightFileWarning(UserWarning):
    """A non-fatal problem in a flight file (implausible but unused channel, non-finite samples)."""


def file_error(path: PathLike, message: str) -> FlightFileError:
    """``FlightFileError("<path>: <message>")`` on one line."""
    return FlightFileError(" ".join(f"{os.fspath(path)}: {message}".splitlines()))


def truncated_list(names: Sequence[str], limit: int = _MAX_LISTED) -> str:
    """``"a, b, c"``, or the first ``limit`` names and ``"… (+N more)"``."""
    shown = ", ".join(names[:limit])
    return shown + (f" … (+{len(names) - limit} more)" if len(names) > limit else "")


def validate(flight: Flight, path: PathLike, needs: Iterable[str] = ("tt",)) -> list[str]:
    """Check a flight read from ``path``; raise on fatal problems, return the warnings.

    Parameters
    ----------
    flight : Flight
    path : str or PathLike
        The file it came from (named in every message).
    needs : iterable of str
        What the caller will use: field names (``"mag_1_uc"``), vector prefixes (``"flux_a"`` →
        ``flux_a_x/y/z``) or groups ``"position"`` (``lat``, ``lon`` and one of ``alt``,
        ``utm_z``, ``ins_alt``), ``"attitude"`` (``ins_roll/pitch/yaw``), ``"date"`` (attribute
        ``date`` or fields ``year`` and ``doy``). ``tt`` is always required.

    Returns
    -------
    list of str
        One-line warnings (without the path); fatal problems raise ``FlightFileError``.
    """
    needs = ("tt", *((needs,) if isinstance(needs, str) else needs))
    check_structure(flight, path)
    check_required(flight, path, needs)
    check_time(flight, path)
    needed = needed_fields(flight, needs)
    warnings = []
    for fields, fatal, message in plausibility_problems(flight):
        if fatal and needed.intersection(fields):
            raise file_error(path, message)
        warnings.append(message)
    report = nonfinite_report(flight)
    if report:
        parts = [format_nonfinite(name, entry) for name, entry in report.items()]
        warnings.append(f"non-finite samples in {len(report)} field(s): " + "; ".join(parts[:5]))
    return warnings + fault_problems(fault_report(flight))


def check_structure(flight: Flight, path: PathLike) -> None:
    """Raise unless the flight has 1-D fields, all of one length, and at least one sample."""
    if not flight.fields:
        raise file_error(path, "no numeric 1-D fields found")
    shapes = {nm: np.shape(values) for nm, values in flight.fields.items()}
    not_1d = [f"{nm} {shape}" for nm, shape in shapes.items() if len(shape) != 1]
    if not_1d:
        raise file_error(path, f"fields must be 1-D; shapes: {truncated_list(not_1d)}")
    lengths = {nm: shape[0] for nm, shape in shapes.items()}
    counts = Counter(lengths.values())
    if len(counts) > 1:
        major = max(counts, key=lambda n: (counts[n], n == lengths.get("tt")))
        odd = [f"{nm} has {n}" for nm, n in lengths.items() if n != major]
        raise file_error(
            path,
            f"fields of different lengths: {truncated_list(odd)} samples, "
            f"while the other {counts[major]} field(s) have {major}",
        )
    if flight.n == 0:
        raise file_error(path, "no samples (0 rows)")


def check_required(flight: Flight, path: PathLike, needs: Iterable[str]) -> None:
    """Raise if a field the caller needs is missing; the message lists what is there."""
    missing = [nm for token in dict.fromkeys(needs) for nm in _resolve(flight, token)[1]]
    if missing:
        raise file_error(
            path,
            f"missing required field(s) {', '.join(missing)}; "
            f"fields present: {truncated_list(flight.names)}",
        )


def check_time(flight: Flight, path: PathLike) -> None:
    """Raise if ``tt`` has non-finite samples or is not strictly increasing."""
    if "tt" not in flight:
        return
    tt = flight.tt
    bad = np.flatnonzero(~np.isfinite(tt))
    if bad.size:
        raise file_error(path, f"tt has {bad.size} non-finite sample(s) (first at index {bad[0]})")
    steps = np.flatnonzero(np.diff(tt) <= 0.0)
    if steps.size:
        k = int(steps[0]) + 1
        raise file_error(
            path,
            f"tt is not strictly increasing: at index {k} t = {tt[k]:.10g} s follows "
            f"t = {tt[k - 1]:.10g} s ({steps.size} such step(s))",
        )


def needed_fields(flight: Flight, needs: Iterable[str]) -> set[str]:
    """Concrete field names (plus ``"date"``) that the tokens in ``needs`` stand for."""
    return {nm for token in needs for nm in _resolve(flight, token)[0]}


def _resolve(flight: Flight, token: str) -> tuple[list[str], list[str]]:
    """(fields the token stands for, readable names of those missing) for one ``needs`` token."""
    if token == "position":
        alt = flight.altitude_name()
        missing = [nm for nm in POSITION_NAMES if nm not in flight]
        missing += [] if alt else ["alt (or utm_z, ins_alt)"]
        return [*POSITION_NAMES, alt or "alt"], missing
    if token == "date":
        ok = "date" in flight.attrs or ("year" in flight and "doy" in flight)
        return ["date", "year", "doy"], [] if ok else ["date (attribute or fields year and doy)"]
    if token == "attitude":
        names = list(ATTITUDE_NAMES)
    elif token not in flight and (
        _VECTOR_RE.match(token) or any(nm in flight for nm in vector_names(token))
    ):
        names = list(vector_names(token))
    else:
        names = [token]
    return names, [nm for nm in names if nm not in flight]


def plausibility_problems(flight: Flight) -> list[Problem]:
    """Unit and range problems of the channels present."""
    found: list[tuple[tuple[str, ...], str, np.ndarray]] = []
    for gate in flight.fluxgates():
        with np.errstate(over="ignore"):  # |1e200 nT| is reported as implausible, not warned on
            magnitude = np.linalg.norm(flight.vector(gate), axis=1)
        found.append((vector_names(gate), f"{gate}_x/y/z", magnitude))
    found += [((nm,), nm, flight[nm]) for nm in flight.scalars()]
    problems: list[Problem] = []
    for fields, label, values in found:
        problem = _magnitude_problem(label, values)
        if problem is not None:
            problems.append((fields, *problem))
    attitude = _attitude_problem(flight)
    if attitude is not None:
        problems.append((ATTITUDE_NAMES, *attitude))
    return problems + _position_date_problems(flight)


def _magnitude_problem(label: str, values: np.ndarray) -> tuple[bool, str] | None:
    """Magnitude in another unit (fatal), or outside the Earth-field range (warning)."""
    finite = np.abs(values[np.isfinite(values)])
    if finite.size == 0:
        return None
    med = float(np.median(finite))
    for low, high, unit, factor in _UNIT_BANDS:
        if low <= med <= high:
            hint = f"looks like {unit}; expected nT (multiply by {factor})"
            return True, f"{label} {hint} (median magnitude {med:.3g})"
    if med > IMPLAUSIBLE_FIELD_NT:
        return True, f"{label} has an implausible median magnitude of {med:.4g} nT"
    low, high = EARTH_FIELD_RANGE_NT
    if not low <= med <= high:
        earth = f"the Earth-field range {low:.0f}–{high:.0f} nT"
        return False, f"{label} median magnitude {med:.0f} nT is outside {earth}"
    return None


def _position_date_problems(flight: Flight) -> list[Problem]:
    """Latitude beyond ±90°, longitude beyond ±360°, a date unreadable or outside IGRF-14."""
    problems: list[Problem] = []
    for name, limit in (("lat", 90.0), ("lon", 360.0)):
        values = flight.fields.get(name, np.empty(0))
        finite = np.abs(values[np.isfinite(values)])
        if finite.size and finite.max() > limit:
            message = f"{name} reaches {finite.max():.4g}, beyond ±{limit:.0f}°; expected degrees"
            problems.append(((name,), True, message))
    try:
        flight.date()
    except (ValueError, OverflowError) as exc:  # ModelDateError: read, but outside IGRF-14
        what = "unusable date" if isinstance(exc, ModelDateError) else "unreadable date"
        problems.append((("date", "year", "doy"), True, f"{what}: {exc}"))
    except KeyError:  # no date at all: a missing field, reported when needed
        pass
    return problems


def _attitude_problem(flight: Flight) -> tuple[bool, str] | None:
    """Attitude stored in radians instead of degrees: ``(definite, message)`` or None.

    Angles beyond 2π can only be degrees. When every finite ``|ins_roll|``, ``|ins_pitch|``,
    ``|ins_yaw|`` is within 2π the unit is ambiguous (a straight northbound line in degrees has
    small angles too), and it is decided by physics, first applicable test wins:

    1. With position, date and a fluxgate: IGRF (NED, at ≤ 200 samples) rotated into the body
       frame under each hypothesis; the median angle to the measured fluxgate direction must be
       < 20° and 5° better than the other hypothesis.
    2. With position only: ``ins_yaw`` against the course over ground from ``lat``/``lon``
       (median < 30°, 5° margin; crab angles stay well below).
    3. Without either: a yaw span above 3 rad at a rate below 20°/s (95th percentile) is a
       turn, which in degrees would exceed 2π: radians (definite); else a warning (ambiguous,
       degrees assumed). A northbound line in degrees whose heading wanders over > 3° slower
       than 0.35°/s is misread here; position or a fluxgate in the file avoids that.
    """
    if any(nm not in flight for nm in ATTITUDE_NAMES):
        return None
    angles = np.column_stack([flight[nm] for nm in ATTITUDE_NAMES])
    finite = np.abs(angles[np.isfinite(angles)])
    if finite.size == 0 or finite.max() > _TWO_PI_TOL:
        return None
    vote = _vote_fluxgate(flight) or _vote_course(flight)
    if vote is not None:
        unit, evidence = vote
        return None if unit == "degrees" else (True, f"{_RADIANS_MSG} ({evidence})")
    yaw = np.unwrap(angles[:, 2][np.isfinite(angles[:, 2])])  # as radians
    span = float(np.ptp(yaw)) if yaw.size > 1 else 0.0
    rate = np.percentile(np.abs(np.diff(yaw)), 95) * flight.sample_rate_hz if span else 0.0
    if span > _YAW_SPAN_RAD and rate < _MAX_YAW_RATE_RAD_S:
        return True, f"{_RADIANS_MSG} (all within ±2π while ins_yaw turns through {span:.2f})"
    return False, "ins_roll/ins_pitch/ins_yaw all within ±2π: unit ambiguous, degrees assumed"


def _vote_fluxgate(flight: Flight) -> tuple[str, str] | None:
    """Which attitude unit makes IGRF, rotated into the body frame, point along the fluxgate."""
    gates = flight.fluxgates()
    if not gates or not _has_position(flight):
        return None
    try:
        date = flight.date()
    except (KeyError, ValueError, OverflowError):
        return None
    lat, lon, alt = flight.position_rad()
    flux = flight.vector(gates[0])
    angles = np.column_stack([flight[nm] for nm in ATTITUDE_NAMES])
    k = _subsample(np.isfinite(np.column_stack([lat, lon, alt, flux, angles])).all(axis=1))
    if k.size < 3 or np.abs(lat[k]).max() > np.pi / 2:
        return None
    try:
        b_ned = igrf_ned(lat[k], lon[k], alt[k], date)
    except ValueError:  # a date outside the model's range
        return None
    errors = {
        unit: _median_angle(nav_to_body(dcm_from_euler(*(angles[k] * scale).T), b_ned), flux[k])
        for unit, scale in _UNIT_SCALES
    }
    return _decide(errors, np.deg2rad(20.0), f"IGRF direction vs {gates[0]}")


def _vote_course(flight: Flight) -> tuple[str, str] | None:
    """Which attitude unit makes ``ins_yaw`` follow the course over ground."""
    if not _has_position(flight):
        return None
    lat, lon, yaw = np.deg2rad(flight["lat"]), np.deg2rad(flight["lon"]), flight["ins_yaw"]
    k = _subsample(np.isfinite(lat) & np.isfinite(lon) & np.isfinite(yaw))
    d_north = np.diff(lat[k]) * WGS84_A_M  # [m]
    d_east = np.diff(lon[k]) * WGS84_A_M * np.cos(lat[k][:-1])  # [m]
    moving = np.hypot(d_north, d_east) > 1.0
    if moving.sum() < 3:
        return None
    course = np.arctan2(d_east, d_north)[moving]
    yaw_mid = yaw[(k[:-1] + k[1:]) // 2][moving]
    errors = {  # wrapped to (-π, π] through the complex exponential
        unit: float(np.median(np.abs(np.angle(np.exp(1j * (yaw_mid * scale - course))))))
        for unit, scale in _UNIT_SCALES
    }
    return _decide(errors, np.deg2rad(30.0), "ins_yaw vs course over ground")


def _has_position(flight: Flight) -> bool:
    """``lat``, ``lon`` and an altitude channel are present."""
    return flight.altitude_name() is not None and all(nm in flight for nm in POSITION_NAMES)


def _subsample(mask: np.ndarray, max_points: int = _MAX_POINTS) -> np.ndarray:
    """Indices of ``mask``, evenly thinned to at most ``max_points``."""
    idx = np.flatnonzero(mask)
    if idx.size > max_points:
        idx = idx[np.linspace(0, idx.size - 1, max_points).round().astype(int)]
    return idx


def _median_angle(a: np.ndarray, b: np.ndarray) -> float:
    """Median angle [rad] between the rows of two (n, 3) arrays (NaN if none is defined)."""
    cosine = np.sum(_unit_rows(a) * _unit_rows(b), axis=1)
    ok = np.isfinite(cosine)
    return float(np.median(np.arccos(np.clip(cosine[ok], -1.0, 1.0)))) if ok.any() else np.nan


def _unit_rows(x: np.ndarray) -> np.ndarray:
    """The rows of an (n, 3) array scaled to length 1, NaN where a row is zero or not finite.
    Each row is first divided by its largest magnitude, so that a value near the float64 limit
    (a damaged sample of 1e307) does not overflow the length."""
    with np.errstate(divide="ignore", invalid="ignore"):  # a zero or non-finite row: NaN
        scaled = x / np.abs(x).max(axis=1, keepdims=True)
        return scaled / np.linalg.norm(scaled, axis=1, keepdims=True)


def _decide(errors: dict[str, float], limit: float, what: str) -> tuple[str, str] | None:
    """The unit whose median error [rad] is below ``limit`` and clearly below the other's."""
    deg, rad = errors["degrees"], errors["radians"]
    if not (np.isfinite(deg) and np.isfinite(rad)):
        return None
    best, other = ("radians", "degrees") if rad < deg else ("degrees", "radians")
    if errors[best] > limit or errors[other] - errors[best] < _MARGIN_RAD:
        return None
    best_deg, other_deg = np.rad2deg(errors[best]), np.rad2deg(errors[other])
    return best, f"{what}: median {best_deg:.1f}° as {best}, {other_deg:.1f}° as {other}"


def nonfinite_report(flight: Flight, max_ranges: int = 5) -> dict[str, dict[str, Any]]:
    """Where each field has NaN or ±inf samples (fields without any are left out).

    Returns
    -------
    dict
        Field name → ``{"count", "samples", "first_index", "last_index", "first_time_s",
        "last_time_s", "ranges", "n_ranges"}``: ``ranges`` are the first ``max_ranges`` of the
        ``n_ranges`` inclusive ``[start, end]`` index runs; times [s] are None without a usable
        ``tt``. Plain Python types (JSON serialisable).
    """
    tt = flight.fields.get("tt")
    report: dict[str, dict[str, Any]] = {}
    for name, values in flight.fields.items():
        idx = np.flatnonzero(~np.isfinite(values))
        if idx.size == 0:
            continue
        breaks = np.flatnonzero(np.diff(idx) > 1)
        starts, ends = idx[np.r_[0, breaks + 1]], idx[np.r_[breaks, idx.size - 1]]
        report[name] = {
            "count": int(idx.size),
            "samples": int(values.size),
            "first_index": int(idx[0]),
            "last_index": int(idx[-1]),
            "first_time_s": _time_at(tt, int(idx[0])),
            "last_time_s": _time_at(tt, int(idx[-1])),
            "ranges": [[int(a), int(b)] for a, b in zip(starts, ends, strict=True)][:max_ranges],
            "n_ranges": int(starts.size),
        }
    return report


def _time_at(tt: np.ndarray | None, index: int) -> float | None:
    """``tt[index]`` [s], or None if there is no usable time there."""
    if tt is None or np.ndim(tt) != 1 or index >= tt.size or not np.isfinite(tt[index]):
        return None
    return float(tt[index])


def format_nonfinite(name: str, entry: dict[str, Any]) -> str:
    """One line for one field of :func:`nonfinite_report`."""
    spans = ", ".join(str(a) if a == b else f"{a}–{b}" for a, b in entry["ranges"])
    more = entry["n_ranges"] - len(entry["ranges"])
    spans += f" (+{more} more ranges)" if more else ""
    t0, t1 = entry["first_time_s"], entry["last_time_s"]
    times = "" if t0 is None or t1 is None else f", t {t0:.10g}–{t1:.10g} s"
    return f"{name}: {entry['count']} of {entry['samples']} non-finite at index {spans}{times}"
