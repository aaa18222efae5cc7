"""A fitted compensation model: fit once on a calibration flight, apply to other flights.

The industry compensates a survey aircraft this way: after each installation it flies a
calibration box, the coefficients are computed once and then applied to every survey flight of
that aircraft. A :class:`CalibrationModel` holds everything that takes:

* ``method`` and its ``settings`` (Tolles–Lawson's band-pass, trim and ridge; the filter's
  :class:`~aeromag_env.compensation.model.FilterConfig`);
* ``coefficients``: the 18 Tolles–Lawson terms [nT] and the correction's constant offset [nT]
  (``tl``), or the filter's state (21), covariance (21×21), process-noise diagonal (21) and
  measurement noise (3×3) at the end of calibration, in physical units, and the samples it had
  processed (the Kalman family);
* ``channels``: the time, fluxgate and scalar channel names; ``mount``: the fluxgate's rotation
  into body axes (vector methods); ``sample_rate_hz`` [Hz] and ``gap_factor`` [-]: what a time
  gap is; ``spike_threshold_nt`` [nT] per magnetometer: the spike test of
  :mod:`aeromag_env.compensation.model_apply`;
* ``calibration``: what the fit saw and how well it did (figures of merit box by box, residual
  statistics the recalibrate check compares against, :mod:`aeromag_env.compensation.model_drift`);
* ``provenance``: the calibration file's SHA-256, the date the model was made, the package
  version.

It applies itself to a whole flight (:meth:`CalibrationModel.apply`:
:mod:`aeromag_env.compensation.model_apply` for Tolles–Lawson,
:mod:`aeromag_env.compensation.model_filter` for the filters) and to samples as they arrive
(:meth:`CalibrationModel.stream`, :mod:`aeromag_env.compensation.model_stream`), with the same
numbers; :mod:`aeromag_env.compensation.model_fit` fits it.

On disk it is JSON (:meth:`CalibrationModel.save`, :func:`load_model`) with ``model_version``
:data:`MODEL_VERSION` and ``kind`` :data:`MODEL_KIND`; a file that is not one, of another
version, or with a field missing or of the wrong shape is a one-line
:class:`~aeromag_env.errors.AeromagError` naming the file and the field.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.atomic import write_text
from aeromag_env.compensation.compensate import Compensation
from aeromag_env.compensation.model import FilterConfig
from aeromag_env.compensation.model_apply import CalibratedTL, tl_compensation
from aeromag_env.compensation.model_checks import SampleChecks
from aeromag_env.compensation.model_filter import CalibratedFilter, filter_compensation
from aeromag_env.compensation.model_stream import SampleStream, filter_stream, tl_stream
from aeromag_env.configs import from_dict, to_dict
from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import ATTITUDE_NAMES, POSITION_NAMES, Flight, vector_names
from aeromag_env.flight.earth_model import model_date
from aeromag_env.flight.mounting import Mount
from aeromag_env.simulation.interference import N_STATES
from aeromag_env.simulation.tolles_lawson_terms import N_TERMS

#: The model file's format version; a file of another version is refused.
MODEL_VERSION = 1
#: The ``kind`` field every model file carries (a JSON file of another kind is refused).
MODEL_KIND = "aeromag-compensation-model"
#: The methods a model can hold: Tolles–Lawson and the recursive (Kalman family) filters.
MODEL_METHODS = ("tl", "kf", "fakf", "rls", "sage-husa", "ding")


class ModelFileError(AeromagError, ValueError):
    """A model file is unreadable, of another version, or has a missing or malformed field."""


@dataclass(frozen=True, kw_only=True)
class CalibrationModel:
    """A compensation fitted on a calibration flight, to apply to other flights of the aircraft.

    Attributes
    ----------
    method : str
        One of :data:`MODEL_METHODS`.
    settings : dict
        ``tl``: ``bandpass_hz`` [Hz] (or None), ``trim`` [samples], ``ridge`` [-],
        ``bt_scale_nt`` [nT]; the filters: the fields of :class:`FilterConfig`.
    coefficients : dict
        ``tl``: ``tolles_lawson`` (18) [nT] and ``offset_nt`` [nT], the constant the correction
        is shifted by (the mean correction over the calibration flight when the band-pass hid
        the constant part, else 0). The filters: ``state`` (21) and ``covariance`` (21×21),
        ``process_noise`` (21, the diagonal of Q) and ``measurement_noise`` (3×3, R), physical
        units (nT, -, s and their squares).
    channels : dict
        ``time`` (``tt``), ``flux`` (a fluxgate prefix) and ``scalar`` (``tl``; else None).
    sample_rate_hz : float
        The calibration flight's sample rate [Hz] (the eddy terms of ``tl`` depend on it).
    gap_factor : float
        A time step above ``gap_factor / sample_rate_hz`` [s] is a gap [-].
    spike_threshold_nt : dict
        Magnetometer name → the spike test's threshold [nT].
    mount : dict or None
        The fluxgate's mount (:meth:`Mount.to_dict`); None for ``tl`` (sensor axes).
    calibration : dict
        Figures of the calibration: ``samples``, ``span_s``, ``selection``, ``fom_nt`` and
        ``fom_boxes`` (box by box), ``residual`` (the statistics the recalibrate check compares
        against).
    provenance : dict
        ``input`` (path or None), ``input_sha256``, ``created`` (ISO 8601 UTC),
        ``package_version``.
    """

    method: str
    settings: dict[str, Any]
    coefficients: dict[str, Any]
    channels: dict[str, Any]
    sample_rate_hz: float
    gap_factor: float
    spike_threshold_nt: dict[str, float]
    mount: dict[str, Any] | None = None
    calibration: dict[str, Any] = field(default_factory=dict)
    provenance: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        check_model(self.to_dict(), "CalibrationModel")

    @property
    def is_filter(self) -> bool:
        """Whether the method is a recursive (Kalman family) filter, not Tolles–Lawson."""
        return self.method != "tl"

    def checks(self) -> SampleChecks:
        """The sample checks fixed at calibration (gap and spike thresholds)."""
        return SampleChecks(
            gap_s=self.gap_factor / self.sample_rate_hz,
            spike_threshold_nt=dict(self.spike_threshold_nt),
        )

    def tl_coefficients(self) -> np.ndarray:
        """The 18 Tolles–Lawson coefficients [nT] (``tl`` only)."""
        return np.asarray(self.coefficients["tolles_lawson"], dtype=float)

    def calibrated_tl(self) -> CalibratedTL:
        """What applying a ``tl`` model takes (:mod:`aeromag_env.compensation.model_apply`)."""
        return CalibratedTL(
            coef=self.tl_coefficients(),
            offset_nt=float(self.coefficients["offset_nt"]),
            bt_scale_nt=float(self.settings["bt_scale_nt"]),
            flux=self.channels["flux"],
            scalar=self.channels["scalar"],
            checks=self.checks(),
            sample_rate_hz=self.sample_rate_hz,
        )

    def filter_config(self) -> FilterConfig:
        """The filter's settings (the Kalman family only)."""
        return from_dict(FilterConfig, {**self.settings, "method": self.method})

    def filter_end(self) -> dict[str, np.ndarray]:
        """The filter at the end of calibration: ``state`` (21,), ``covariance`` (21, 21),
        ``process_noise`` (21,), ``measurement_noise`` (3, 3), physical units, and ``samples``
        (the samples it had processed)."""
        return {k: np.asarray(v, dtype=float) for k, v in self.coefficients.items()}

    def calibrated_filter(self) -> CalibratedFilter:
        """What continuing a Kalman-family model takes (:mod:`aeromag_env.compensation.
        model_filter`)."""
        end = self.filter_end()
        mount = self.mount_object()
        return CalibratedFilter(
            cfg=self.filter_config(),
            end={k: v for k, v in end.items() if k != "samples"},
            samples=int(end["samples"]),
            rotation=None if mount is None else mount.rotation,
            flux=self.channels["flux"],
            checks=self.checks(),
            sample_rate_hz=self.sample_rate_hz,
        )

    def mount_object(self) -> Mount | None:
        """The fluxgate's mount as a :class:`Mount` (None: sensor axes are body axes)."""
        if self.mount is None:
            return None
        return Mount(rotation=np.asarray(self.mount["rotation"], float), source="file")

    def input_channels(self) -> tuple[str, ...]:
        """The channel names a flight needs for this model (a filter's: with ``alt``, the first
        altitude channel a file may have)."""
        flux = vector_names(self.channels["flux"])
        if self.method == "tl":
            return (self.channels["time"], *flux, self.channels["scalar"])
        return (self.channels["time"], *POSITION_NAMES, "alt", *ATTITUDE_NAMES, *flux)

    def missing_channels(self, flight: Flight) -> list[str]:
        """The channels of :meth:`input_channels` that ``flight`` lacks (a filter's altitude may
        be any of a file's altitude channels)."""
        missing = [nm for nm in self.input_channels() if nm != "alt" and nm not in flight]
        if self.is_filter and flight.altitude_name() is None:
            missing.append("alt")
        return missing

    def apply(self, flight: Flight, residual_mask: np.ndarray | None = None) -> Compensation:
        """Compensate ``flight`` with this model: Tolles–Lawson with the calibrated
        coefficients, or the filter continued from its calibrated state (it keeps adapting).

        ``residual_mask`` (n,) bool: the samples the recalibrate residual (``settings["drift"]``)
        is measured on (None: all). A flight lacking one of the model's channels, or a filter's
        flight without a date, is a one-line error.
        """
        missing = self.missing_channels(flight)
        if missing:
            raise AeromagError(
                f"the flight lacks channel(s) {', '.join(missing)} that the {self.method} model "
                f"needs ({', '.join(self.input_channels())}); recalibrate with this flight's "
                "channels"
            )
        if self.method == "tl":
            return tl_compensation(self.calibrated_tl(), flight, self._settings(), residual_mask)
        try:
            date = model_date(flight)
        except KeyError as e:
            raise AeromagError(f"the {self.method} model needs the flight's date: {e}") from None
        cal = self.calibrated_filter()
        return filter_compensation(cal, flight, date, self._settings(), residual_mask)

    def stream(
        self, header: Sequence[str] | None = None, date: _dt.datetime | str | None = None
    ) -> SampleStream:
        """A :class:`~aeromag_env.compensation.model_stream.SampleStream`: ``update(sample)``
        with one sample as a mapping of channel name → value, answering the compensated ones
        (the same numbers as :meth:`apply` on the whole flight).

        ``header`` (the channels the samples will have) picks a filter's altitude channel and
        its ``diurnal``; ``date`` is a filter's flight date (None: the first sample's ``year``
        and ``doy``). A ``tl`` model needs neither.
        """
        if self.method == "tl":
            return tl_stream(self.calibrated_tl())
        return filter_stream(self.calibrated_filter(), header, date)

    def _settings(self) -> dict[str, Any]:
        """The settings block of an applied model: the method's, the model's provenance, and
        the same ``flux`` / ``remove_mean`` keys a fit's settings have."""
        extra = {"scalar": self.channels["scalar"]} if self.method == "tl" else {}
        return {
            **self.settings,
            **extra,
            "flux": self.channels["flux"],
            "remove_mean": bool(self.settings.get("remove_mean", False)),
            "model": {
                "provenance": self.provenance,
                "calibration_samples": self.calibration.get("samples"),
            },
        }

    def to_dict(self) -> dict[str, Any]:
        """The model as the JSON object :meth:`save` writes."""
        return {
            "kind": MODEL_KIND,
            "model_version": MODEL_VERSION,
            "method": self.method,
            "settings": _plain(self.settings),
            "coefficients": _plain(self.coefficients),
            "channels": dict(self.channels),
            "sample_rate_hz": float(self.sample_rate_hz),
            "gap_factor": float(self.gap_factor),
            "spike_threshold_nt": {k: float(v) for k, v in self.spike_threshold_nt.items()},
            "mount": _plain(self.mount),
            "calibration": _plain(self.calibration),
            "provenance": dict(self.provenance),
        }

    def to_json(self) -> str:
        """:meth:`to_dict` as JSON text (non-finite figures as ``null``)."""
        return json.dumps(_finite_or_null(self.to_dict()), indent=1, allow_nan=False) + "\n"

    def save(self, path: str | Path) -> Path:
        """Write the model to ``path`` atomically (temporary file, then rename); returns it."""
        return write_text(Path(path), self.to_json())


def load_model(path: str | Path) -> CalibrationModel:
    """Read a model file written by :meth:`CalibrationModel.save`.

    Raises
    ------
    ModelFileError
        One line naming the file and what is wrong: unreadable, not JSON, not a model, another
        ``model_version``, a field missing or malformed.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except OSError as e:
        raise ModelFileError(f"model file {path}: cannot read it ({e.strerror or e})") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise ModelFileError(f"model file {path}: not JSON ({e})") from None
    return model_from_dict(data, str(path))


def model_from_dict(data: Any, where: str = "model") -> CalibrationModel:
    """A :class:`CalibrationModel` from its JSON object, checked (:func:`check_model`)."""
    check_model(data, f"model file {where}")
    names = CalibrationModel.__dataclass_fields__
    keep = {k: v for k, v in data.items() if k in names}
    return CalibrationModel(**keep)


def check_model(data: Any, where: str) -> None:
    """One-line :class:`ModelFileError` naming ``where`` and the field when ``data`` is not a
    model of this version: kind, version, method, channels, rate, coefficients' shapes."""
    if not isinstance(data, dict) or data.get("kind") != MODEL_KIND:
        raise ModelFileError(f"{where}: not an aeromag compensation model (no kind {MODEL_KIND!r})")
    if data.get("model_version") != MODEL_VERSION:
        raise ModelFileError(
            f"{where}: model_version {data.get('model_version')!r} is not {MODEL_VERSION}, the "
            "version this aeromag reads; recalibrate with this version"
        )
    for name in REQUIRED_FIELDS:
        if name not in data:
            raise ModelFileError(f"{where}: field {name!r} is missing")
    method = data["method"]
    if method not in MODEL_METHODS:
        raise ModelFileError(
            f"{where}: method must be one of {', '.join(MODEL_METHODS)}, got {method!r}"
        )
    _check_positive(data, "sample_rate_hz", where, "Hz")
    _check_positive(data, "gap_factor", where, "-")
    _check_channels(data["channels"], method, where)
    thresholds = data["spike_threshold_nt"]
    if not isinstance(thresholds, dict) or not all(
        isinstance(v, int | float) and v > 0 for v in thresholds.values()
    ):
        raise ModelFileError(f"{where}: spike_threshold_nt must map channels to numbers > 0 [nT]")
    if method == "tl":
        _check_array(data["coefficients"], "tolles_lawson", (N_TERMS,), where)
        _check_array(data["coefficients"], "offset_nt", (), where)
    else:
        for name, shape in FILTER_END_SHAPES.items():
            _check_array(data["coefficients"], name, shape, where)
        try:
            from_dict(FilterConfig, {**data["settings"], "method": method})
        except (AeromagError, TypeError) as e:
            raise ModelFileError(f"{where}: settings: {e}") from None


#: The fields every model file has (besides ``kind`` and ``model_version``).
REQUIRED_FIELDS = (
    "method",
    "settings",
    "coefficients",
    "channels",
    "sample_rate_hz",
    "gap_factor",
    "spike_threshold_nt",
)
#: The shapes of the filter's end-of-calibration arrays in ``coefficients``.
FILTER_END_SHAPES = {
    "state": (N_STATES,),
    "covariance": (N_STATES, N_STATES),
    "process_noise": (N_STATES,),
    "measurement_noise": (3, 3),
    "samples": (),
}


def _check_positive(data: dict[str, Any], name: str, where: str, unit: str) -> None:
    value = data.get(name)
    ok = isinstance(value, int | float) and not isinstance(value, bool)
    if not (ok and value > 0 and math.isfinite(value)):  # type: ignore[operator, arg-type]
        raise ModelFileError(f"{where}: {name} must be a finite number > 0 [{unit}], got {value!r}")


def _check_channels(channels: Any, method: str, where: str) -> None:
    needed = ("time", "flux", "scalar") if method == "tl" else ("time", "flux")
    if not isinstance(channels, dict):
        raise ModelFileError(f"{where}: channels must be an object naming {', '.join(needed)}")
    for name in needed:
        if not isinstance(channels.get(name), str) or not channels[name]:
            raise ModelFileError(f"{where}: channels.{name} must name a channel")


def _check_array(block: Any, name: str, shape: tuple[int, ...], where: str) -> None:
    if not isinstance(block, dict) or name not in block:
        raise ModelFileError(f"{where}: coefficients.{name} is missing")
    try:
        values = np.asarray(block[name], dtype=float)
    except (TypeError, ValueError):
        raise ModelFileError(f"{where}: coefficients.{name} must be numbers") from None
    if values.shape != shape:
        raise ModelFileError(
            f"{where}: coefficients.{name} must have shape {shape}, got {values.shape}"
        )
    if not np.all(np.isfinite(values)):
        raise ModelFileError(f"{where}: coefficients.{name} has non-finite values")


def _plain(value: Any) -> Any:
    """Arrays and numpy numbers as lists and floats, recursively (for JSON)."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if hasattr(value, "__dataclass_fields__"):
        return _plain(to_dict(value))
    return value


def _finite_or_null(value: Any) -> Any:
    """NaN and infinities as None (JSON has no such numbers)."""
    if isinstance(value, dict):
        return {k: _finite_or_null(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_finite_or_null(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
