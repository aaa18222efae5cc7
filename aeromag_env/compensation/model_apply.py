"""Apply a calibrated Tolles–Lawson model to a flight, whole or one sample at a time.

:func:`apply_tl` compensates a whole flight and :class:`TollesLawsonStream` the same flight fed
sample by sample; both give the same numbers (to rounding, far below 1e-9 nT), because they
share the sample checks (:mod:`aeromag_env.compensation.model_checks`) and the arithmetic:

* the design row of sample k (:func:`~aeromag_env.simulation.tolles_lawson_terms.design_matrix`'s
  18 terms) uses the per-sample central difference of the fluxgate inside a run of usable
  fluxgate samples, one-sided at the run's ends, none for a run of one sample (NaN output);
* the correction is ``design @ coef − offset_nt``, the offset fixed at calibration (a
  band-passed fit cannot see the constant part; the calibration flight's mean correction is
  removed, as MagNav.jl does over the flight it compensates), so that no flight-wide mean is
  needed and a stream can be compensated as it arrives;
* the compensated scalar is ``scalar − correction`` where the scalar and the fluxgate are usable,
  else NaN (a stream reports the sample and skips it).

A stream answers sample k once sample k + 2 has arrived (the spike test of k + 1 needs k + 2,
and k's central difference needs to know whether k + 1 is usable): 0.2 s at 10 Hz;
:meth:`TollesLawsonStream.flush` answers the last two at the end.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from aeromag_env.compensation.calibration_model import CalibrationModel
from aeromag_env.compensation.model_checks import segment_starts, spike_flags
from aeromag_env.errors import AeromagError
from aeromag_env.simulation.tolles_lawson_terms import INDUCED_PAIRS

#: Samples a Tolles–Lawson stream holds back before it answers one [samples].
TL_LOOKAHEAD = 2


@dataclass(frozen=True)
class Flags:
    """The checks' verdict on each sample of a flight (:func:`tl_flags`).

    Attributes
    ----------
    starts : (n,) bool, a continuous segment starts here
    flux_ok : (n,) bool, the fluxgate is finite and shows no spike
    valid : (n,) bool, ``flux_ok`` and the scalar is finite and shows no spike
    """

    starts: np.ndarray
    flux_ok: np.ndarray
    valid: np.ndarray


def tl_flags(
    model: CalibrationModel, tt: np.ndarray, flux: np.ndarray, scalar: np.ndarray
) -> Flags:
    """The sample checks of ``model`` on a flight: time ``tt`` (n,) [s], fluxgate (n, 3) and
    scalar (n,) [nT]."""
    starts = segment_starts(tt, model.gap_factor / model.sample_rate_hz)
    names = model.channels
    thr = model.spike_threshold_nt
    flux_ok = np.all(np.isfinite(flux), axis=1) & ~spike_flags(flux, starts, thr[names["flux"]])
    scalar_ok = np.isfinite(scalar) & ~spike_flags(scalar, starts, thr[names["scalar"]])
    return Flags(starts=starts, flux_ok=flux_ok, valid=flux_ok & scalar_ok)


def run_differences(b: np.ndarray, ok: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Per-sample central difference of ``b`` (n, 3) inside runs of ``ok`` samples (a run never
    crosses a segment start), one-sided at a run's ends, NaN for a run of one sample and
    outside the runs [b's unit per sample]."""
    joined = np.zeros(b.shape[0], dtype=bool)  # k and k−1 in one run
    joined[1:] = ok[1:] & ok[:-1] & ~starts[1:]
    has_prev = joined
    has_next = np.zeros_like(joined)
    has_next[:-1] = joined[1:]
    prev = np.vstack([b[:1], b[:-1]])
    nxt = np.vstack([b[1:], b[-1:]])
    both = has_prev & has_next
    out = np.full(b.shape, np.nan)
    out[both] = (nxt[both] - prev[both]) / 2.0
    only_next = has_next & ~has_prev
    out[only_next] = nxt[only_next] - b[only_next]
    only_prev = has_prev & ~has_next
    out[only_prev] = b[only_prev] - prev[only_prev]
    return out


def design_rows(b: np.ndarray, db: np.ndarray, bt_scale_nt: float) -> np.ndarray:
    """The 18 Tolles–Lawson terms (n, 18) from the fluxgate ``b`` (n, 3) [nT] and its
    per-sample difference ``db`` (n, 3) [nT] (the terms of
    :func:`~aeromag_env.simulation.tolles_lawson_terms.design_matrix`)."""
    cos = b / np.linalg.norm(b, axis=1, keepdims=True)
    induced = np.column_stack([cos[:, i] * b[:, j] for i, j in INDUCED_PAIRS]) / bt_scale_nt
    eddy = (cos[:, :, None] * db[:, None, :]).reshape(-1, 9) / bt_scale_nt
    return np.hstack([cos, induced, eddy])


def tl_correction(model: CalibrationModel, b: np.ndarray, db: np.ndarray) -> np.ndarray:
    """The scalar interference the model predicts (n,) [nT]: ``design @ coef − offset``."""
    coef = model.tl_coefficients()
    rows = design_rows(b, db, float(model.settings["bt_scale_nt"]))
    return np.sum(rows * coef, axis=1) - float(model.coefficients["offset_nt"])


def apply_tl(
    model: CalibrationModel, tt: np.ndarray, flux: np.ndarray, scalar: np.ndarray
) -> tuple[np.ndarray, np.ndarray, Flags]:
    """Compensate a whole flight with a Tolles–Lawson model.

    Parameters
    ----------
    model : CalibrationModel
        A ``tl`` model.
    tt : ndarray, shape (n,)
        Time [s], strictly increasing.
    flux : ndarray, shape (n, 3)
        The fluxgate the model was fitted with, in its own axes [nT].
    scalar : ndarray, shape (n,)
        The uncompensated scalar magnetometer [nT].

    Returns
    -------
    compensated : ndarray, shape (n,)
        ``scalar − correction`` [nT], NaN at flagged samples.
    correction : ndarray, shape (n,)
        The predicted interference [nT], NaN where the fluxgate is flagged.
    flags : Flags
    """
    if model.method != "tl":
        raise AeromagError(f"apply_tl needs a tl model, got {model.method!r}")
    flags = tl_flags(model, tt, flux, scalar)
    db = run_differences(flux, flags.flux_ok, flags.starts)
    correction = tl_correction(model, flux, db)
    compensated = np.where(flags.valid, scalar - correction, np.nan)
    return compensated, correction, flags


@dataclass(frozen=True)
class StreamOutput:
    """One answered sample of a stream.

    Attributes
    ----------
    time_s : float
        The sample's time [s].
    value_nt : float or None
        The compensated field [nT]; None for a flagged sample.
    problem : str or None
        Why a flagged sample has no value (one line), else None.
    """

    time_s: float
    value_nt: float | None
    problem: str | None = None


class TollesLawsonStream:
    """A Tolles–Lawson model applied to samples as they arrive (bounded memory).

    :meth:`update` takes one sample and returns the samples it can now answer (the one
    :data:`TL_LOOKAHEAD` samples back, or none yet); :meth:`flush` answers the rest at the end.
    The answers equal :func:`apply_tl` on the whole flight. The stream holds the last four
    samples and nothing that grows.

    Parameters
    ----------
    model : CalibrationModel
        A ``tl`` model.
    """

    def __init__(self, model: CalibrationModel) -> None:
        if model.method != "tl":
            raise AeromagError(f"TollesLawsonStream needs a tl model, got {model.method!r}")
        self.model = model
        self._gap_s = model.gap_factor / model.sample_rate_hz
        self._thr_flux = model.spike_threshold_nt[model.channels["flux"]]
        self._thr_scalar = model.spike_threshold_nt[model.channels["scalar"]]
        # each entry: [t, flux (3,), scalar, starts, flux_ok, scalar_ok]; ok None until known
        self._held: deque[list] = deque(maxlen=TL_LOOKAHEAD + 2)
        self._last_t = -np.inf

    def update(self, time_s: float, flux: np.ndarray, scalar: float) -> list[StreamOutput]:
        """Take one sample: time [s], fluxgate (3,) [nT], scalar [nT]. Returns the answered
        samples (zero or one).

        Raises
        ------
        AeromagError
            A time not after the previous sample's (the caller reports and skips it).
        """
        if not time_s > self._last_t:
            raise AeromagError(
                f"time {time_s!r} s is not after the previous sample's {self._last_t:g} s"
            )
        start = not (time_s - self._last_t <= self._gap_s)
        self._last_t = time_s
        self._held.append(
            [float(time_s), np.asarray(flux, float), float(scalar), start, None, None]
        )
        out: list[StreamOutput] = []
        if len(self._held) >= 2:
            self._check(len(self._held) - 2, has_next=True)
        if len(self._held) >= TL_LOOKAHEAD + 1:
            out.append(self._answer(len(self._held) - 1 - TL_LOOKAHEAD))
        return out

    def flush(self) -> list[StreamOutput]:
        """Answer the samples still held (at the end of the stream); the stream is then empty."""
        if not self._held:
            return []
        self._check(len(self._held) - 1, has_next=False)
        first = max(0, len(self._held) - TL_LOOKAHEAD)
        out = [self._answer(i, at_end=True) for i in range(first, len(self._held))]
        self._held.clear()
        self._last_t = -np.inf
        return out

    def _check(self, i: int, has_next: bool) -> None:
        """Decide held sample ``i``'s flags (it needs its neighbours)."""
        _t, b, s, start, _, _ = self._held[i]
        prev = self._held[i - 1] if i > 0 and not start else None
        nxt = self._held[i + 1] if has_next and not self._held[i + 1][3] else None
        spike_b = spike_s = False
        if prev is not None and nxt is not None:
            spike_b = _stands_out(b, prev[1], nxt[1]) > self._thr_flux
            spike_s = _stands_out(np.array([s]), np.array([prev[2]]), np.array([nxt[2]])) > (
                self._thr_scalar
            )
        self._held[i][4] = bool(np.all(np.isfinite(b))) and not spike_b
        self._held[i][5] = bool(np.isfinite(s)) and not spike_s

    def _answer(self, i: int, at_end: bool = False) -> StreamOutput:
        """The output of held sample ``i`` (its flags and its neighbours' are known)."""
        t, b, s, start, flux_ok, scalar_ok = self._held[i]
        if not flux_ok or not scalar_ok:
            what = "fluxgate" if not flux_ok else "scalar"
            return StreamOutput(t, None, f"{what} non-finite or a spike at t = {t:g} s")
        prev = self._held[i - 1] if i > 0 else [None] * 6
        nxt = self._held[i + 1] if i + 1 < len(self._held) else [None] * 6
        has_prev = bool(prev[4]) and not start
        has_next = bool(nxt[4]) and not nxt[3]
        if has_prev and has_next:
            db = (nxt[1] - prev[1]) / 2.0  # type: ignore[operator]
        elif has_next:
            db = nxt[1] - b
        elif has_prev:
            db = b - prev[1]
        else:
            return StreamOutput(t, None, f"fluxgate has no usable neighbour at t = {t:g} s")
        correction = tl_correction(self.model, b[None, :], db[None, :])[0]
        return StreamOutput(t, float(s - correction))


def _stands_out(x: np.ndarray, prev: np.ndarray, nxt: np.ndarray) -> float:
    """:func:`~aeromag_env.compensation.model_checks.spike_statistic` of one sample."""
    back, ahead = x - prev, x - nxt
    with np.errstate(invalid="ignore"):
        same = (np.sign(back) == np.sign(ahead)) & (back != 0)
        stat = np.where(same, np.minimum(np.abs(back), np.abs(ahead)), 0.0)
    stat = np.where(np.isfinite(stat), stat, 0.0)
    return float(stat.max())


class SampleStream:
    """A model's stream fed with samples as mappings of channel name → value.

    Wraps :class:`TollesLawsonStream` (the only streaming form so far: a Kalman-family model
    is refused with a one-line error). :attr:`columns` are the channels each sample needs and
    :attr:`output_name` the compensated channel's name (as ``compensate`` writes it).
    """

    def __init__(self, model: CalibrationModel) -> None:
        from aeromag_env.compensation.compensate import output_names

        if model.method != "tl":
            raise AeromagError(
                f"streaming supports tl models only; this model is {model.method} (apply it to a "
                "whole flight with compensate --model, or calibrate a tl model to stream)"
            )
        self.model = model
        self.columns = model.input_channels()
        names = model.channels
        self.output_name = output_names("tl", names["flux"], names["scalar"])[0]
        self._flux = self.columns[1:4]
        self._stream = TollesLawsonStream(model)

    def update(self, sample: Mapping[str, float]) -> list[StreamOutput]:
        """Take one sample (every name of :attr:`columns`); return the answered samples."""
        time = float(sample[self.columns[0]])
        flux = np.array([float(sample[c]) for c in self._flux])
        return self._stream.update(time, flux, float(sample[self.columns[4]]))

    def flush(self) -> list[StreamOutput]:
        """Answer the samples still held, at the end of the stream."""
        return self._stream.flush()
