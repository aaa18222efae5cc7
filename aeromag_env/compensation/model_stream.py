"""A calibrated model's stream fed with samples as mappings of channel name → value.

:class:`SampleStream` is what :meth:`CalibrationModel.stream
<aeromag_env.compensation.calibration_model.CalibrationModel.stream>` returns: it names the
channels each sample needs (:attr:`SampleStream.columns`) and the channels it answers
(:attr:`SampleStream.output_names`, as ``compensate`` writes them), reads each sample's values
by name and hands them to the stream of its kind — :class:`~aeromag_env.compensation.
model_apply.TollesLawsonStream` or :class:`~aeromag_env.compensation.model_filter.
FilterStream` — whose answers equal the model applied to the whole flight.

A filter's stream needs the flight's date (the Earth field's epoch): given, or read from the
first sample's ``year`` and ``doy`` as a file's would be (:meth:`Flight.date
<aeromag_env.flight.data.Flight.date>`).
"""

from __future__ import annotations

import datetime as _dt
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from aeromag_env.compensation.model_apply import CalibratedTL, StreamOutput, TollesLawsonStream
from aeromag_env.compensation.model_filter import CalibratedFilter, FilterStream
from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import (
    ALTITUDE_NAMES,
    ATTITUDE_NAMES,
    POSITION_NAMES,
    Flight,
    vector_names,
)

#: The channels a first sample gives the date with, when no date is given.
DATE_CHANNELS = ("year", "doy")


class SampleStream:
    """A stream of samples as mappings (module docstring); use :func:`tl_stream` or
    :func:`filter_stream` to make one.

    Attributes
    ----------
    columns : tuple of str
        The channels each sample must have (the time first).
    output_names : tuple of str
        The compensated channels each answer gives values for, in order.
    """

    def __init__(
        self,
        columns: tuple[str, ...],
        output_names: tuple[str, ...],
        feed: Callable[[Mapping[str, float]], list[StreamOutput]],
        flush: Callable[[], list[StreamOutput]],
    ) -> None:
        self.columns = columns
        self.output_names = output_names
        self._feed = feed
        self._flush = flush

    @property
    def time_name(self) -> str:
        """The time channel's name."""
        return self.columns[0]

    def update(self, sample: Mapping[str, float]) -> list[StreamOutput]:
        """Take one sample (every name of :attr:`columns`); return the answered samples (each
        answer comes once the samples after it that its checks need have arrived)."""
        return self._feed(sample)

    def flush(self) -> list[StreamOutput]:
        """Answer the samples still held, at the end of the stream."""
        return self._flush()


def tl_stream(tl: CalibratedTL) -> SampleStream:
    """The stream of calibrated Tolles–Lawson coefficients: time, fluxgate, scalar in."""
    core = TollesLawsonStream(tl)
    flux = vector_names(tl.flux)
    columns = ("tt", *flux, tl.scalar)

    def feed(sample: Mapping[str, float]) -> list[StreamOutput]:
        b = np.array([float(sample[c]) for c in flux])
        return core.update(float(sample["tt"]), b, float(sample[tl.scalar]))

    return SampleStream(columns, (tl.output_name,), feed, core.flush)


def filter_stream(
    cal: CalibratedFilter,
    header: Sequence[str] | None = None,
    date: _dt.datetime | str | None = None,
) -> SampleStream:
    """The stream of a calibrated filter: time, position, attitude, fluxgate (and ``diurnal``
    when the header has it) in.

    Parameters
    ----------
    cal : CalibratedFilter
    header : sequence of str or None
        The channels the samples will have: the altitude is the first of
        :data:`~aeromag_env.flight.data.ALTITUDE_NAMES` there (as a file's), ``diurnal`` is used
        when there; None: ``alt``, no ``diurnal``.
    date : datetime, ISO 8601 text or None
        The flight's date; None: the first sample's ``year`` and ``doy`` (then columns too).
    """
    names = set(header or ())
    altitude = next((n for n in ALTITUDE_NAMES if n in names), "alt")
    diurnal = "diurnal" in names
    flux = vector_names(cal.flux)
    columns: tuple[str, ...] = ("tt", *POSITION_NAMES, altitude, *ATTITUDE_NAMES, *flux)
    columns += ("diurnal",) * diurnal + (DATE_CHANNELS if date is None else ())
    cores: list[FilterStream] = []
    if date is not None:
        cores.append(FilterStream(cal, _as_date(date)))

    def feed(sample: Mapping[str, float]) -> list[StreamOutput]:
        if not cores:
            cores.append(FilterStream(cal, first_sample_date(sample)))
        return cores[0].update(
            float(sample["tt"]),
            _three(sample, (*POSITION_NAMES, altitude)),
            _three(sample, ATTITUDE_NAMES),
            np.array([float(sample[c]) for c in flux]),
            float(sample["diurnal"]) if diurnal else None,
        )

    def flush() -> list[StreamOutput]:
        return cores[0].flush() if cores else []

    return SampleStream(columns, cal.output_names, feed, flush)


def _three(sample: Mapping[str, float], names: Sequence[str]) -> tuple[float, float, float]:
    a, b, c = (float(sample[n]) for n in names)
    return a, b, c


def first_sample_date(sample: Mapping[str, float]) -> _dt.datetime:
    """The date a file with this first sample would have: its ``year`` and ``doy``; a one-line
    error naming them when they are not there or not a date IGRF-14 covers."""
    missing = [c for c in DATE_CHANNELS if c not in sample]
    if missing:
        raise AeromagError(
            "a filter's stream needs the flight's date: give it, or year and doy columns"
        )
    fields = {"tt": np.array([0.0]), **{c: np.array([float(sample[c])]) for c in DATE_CHANNELS}}
    try:
        return Flight(fields, {}).date()
    except (KeyError, ValueError, OverflowError) as e:
        raise AeromagError(f"the stream's date: {e}") from None


def _as_date(date: _dt.datetime | str) -> _dt.datetime:
    """``date`` as the Earth field's epoch; a one-line error when IGRF-14 cannot use it."""
    fields = {"tt": np.array([0.0])}
    try:
        return Flight(fields, {"date": date if isinstance(date, str) else date.isoformat()}).date()
    except (KeyError, ValueError, OverflowError) as e:
        raise AeromagError(f"the stream's date: {e}") from None
