"""Apply calibrated Tolles–Lawson coefficients to a flight, whole or one sample at a time.

:func:`apply_tl` compensates a whole flight and :class:`TollesLawsonStream` the same flight fed
sample by sample with a :class:`CalibratedTL` (what a
:class:`~aeromag_env.compensation.calibration_model.CalibrationModel` of method ``tl`` holds);
both give the same numbers (to rounding, far below 1e-9 nT), because they share the sample
checks (:mod:`aeromag_env.compensation.model_checks`) and the arithmetic:

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

import itertools
from collections import deque
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from aeromag_env.compensation.compensate import Compensation, output_names
from aeromag_env.compensation.model_checks import SampleChecks
from aeromag_env.compensation.model_drift import tl_residual
from aeromag_env.compensation.samples import flight_samples
from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import Flight
from aeromag_env.simulation.tolles_lawson_terms import INDUCED_PAIRS

#: Samples a Tolles–Lawson stream holds back before it answers one [samples].
TL_LOOKAHEAD = 2


@dataclass(frozen=True)
class CalibratedTL:
    """Tolles–Lawson coefficients fixed at calibration, and what applying them needs.

    Attributes
    ----------
    coef : (18,) the Tolles–Lawson coefficients [nT]
    offset_nt : the constant the correction is shifted by [nT]
    bt_scale_nt : the design matrix's field scale [nT]
    flux, scalar : the fluxgate prefix and the scalar magnetometer's name
    checks : the sample checks fixed at calibration
    sample_rate_hz : the calibration's sample rate [Hz] (the recalibrate residual's band-pass)
    """

    coef: np.ndarray
    offset_nt: float
    bt_scale_nt: float
    flux: str
    scalar: str
    checks: SampleChecks
    sample_rate_hz: float

    @property
    def output_name(self) -> str:
        """The compensated channel's name, as ``compensate`` writes it (``aeromag_mag_1_c``)."""
        return output_names("tl", self.flux, self.scalar)[0]


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


def tl_flags(tl: CalibratedTL, tt: np.ndarray, flux: np.ndarray, scalar: np.ndarray) -> Flags:
    """The sample checks on a flight: time ``tt`` (n,) [s], fluxgate (n, 3) and scalar (n,)
    [nT]."""
    starts = tl.checks.starts(tt)
    flux_ok = tl.checks.usable(tl.flux, flux, starts)
    scalar_ok = tl.checks.usable(tl.scalar, scalar, starts)
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


def tl_correction(tl: CalibratedTL, b: np.ndarray, db: np.ndarray) -> np.ndarray:
    """The scalar interference the coefficients predict (n,) [nT]: ``design @ coef − offset``."""
    rows = design_rows(b, db, tl.bt_scale_nt)
    return np.sum(rows * tl.coef, axis=1) - tl.offset_nt


def apply_tl(
    tl: CalibratedTL, tt: np.ndarray, flux: np.ndarray, scalar: np.ndarray
) -> tuple[np.ndarray, np.ndarray, Flags]:
    """Compensate a whole flight with calibrated Tolles–Lawson coefficients.

    Parameters
    ----------
    tl : CalibratedTL
    tt : ndarray, shape (n,)
        Time [s], strictly increasing.
    flux : ndarray, shape (n, 3)
        The fluxgate the coefficients were fitted with, in its own axes [nT].
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
    flags = tl_flags(tl, tt, flux, scalar)
    db = run_differences(flux, flags.flux_ok, flags.starts)
    correction = tl_correction(tl, flux, db)
    compensated = np.where(flags.valid, scalar - correction, np.nan)
    return compensated, correction, flags


def tl_compensation(
    tl: CalibratedTL, flight: Flight, settings: dict[str, Any], mask: np.ndarray | None = None
) -> Compensation:
    """:func:`apply_tl` on a flight as a :class:`~aeromag_env.compensation.compensate.
    Compensation` (the jobs score and write it as a fit's), with ``settings`` and the residual
    the recalibrate check compares in ``settings["drift"]`` (measured on ``mask``, (n,) bool;
    None: every sample)."""
    flux, scalar = flight.vector(tl.flux), flight[tl.scalar]
    after, _correction, flags = apply_tl(tl, flight.tt, flux, scalar)
    parts = segment_slices(flags.starts)
    shown = after if mask is None else np.where(mask, after, np.nan)
    samples = flight_samples(flight, [tl.flux, tl.scalar], [])
    return Compensation(
        method="tl",
        settings={**settings, "drift": tl_residual(shown, flux, tl.sample_rate_hz, parts)},
        coefficients={"tolles_lawson": tl.coef.tolist(), "offset_nt": tl.offset_nt},
        fields={tl.output_name: after},
        total_before=np.asarray(scalar, float),
        total_after=after,
        model_total=None,
        nonfinite=int(np.sum(~flags.valid)),
        samples=replace(samples, valid=flags.valid, segments=parts),
    )


def segment_slices(starts: np.ndarray) -> list[slice]:
    """The continuous segments as slices, from their starts (n,) bool."""
    edges = [*np.flatnonzero(starts), starts.size]
    return [slice(int(a), int(b)) for a, b in itertools.pairwise(edges)]


@dataclass(frozen=True)
class StreamOutput:
    """One answered sample of a stream.

    Attributes
    ----------
    time_s : float
        The sample's time [s].
    values_nt : tuple of float, or None
        The compensated field [nT] (one value for ``tl``, the three axes for a filter); None
        for a flagged sample.
    problem : str or None
        Why a flagged sample has no value (one line), else None.
    """

    time_s: float
    values_nt: tuple[float, ...] | None
    problem: str | None = None


@dataclass
class _Held:
    """A sample a Tolles–Lawson stream holds: its time [s], fluxgate (3,) and scalar [nT],
    whether it starts a segment, and its checks' verdicts (None until its next sample came)."""

    t: float
    b: np.ndarray
    s: float
    start: bool
    flux_ok: bool | None = None
    scalar_ok: bool | None = None


class TollesLawsonStream:
    """Calibrated Tolles–Lawson coefficients applied to samples as they arrive (bounded memory).

    :meth:`update` takes one sample and returns the samples it can now answer (the one
    :data:`TL_LOOKAHEAD` samples back, or none yet); :meth:`flush` answers the rest at the end.
    The answers equal :func:`apply_tl` on the whole flight. The stream holds the last four
    samples and nothing that grows.
    """

    def __init__(self, tl: CalibratedTL) -> None:
        self.tl = tl
        self._held: deque[_Held] = deque(maxlen=TL_LOOKAHEAD + 2)
        self._last_t = -np.inf

    def update(self, time_s: float, flux: np.ndarray, scalar: float) -> list[StreamOutput]:
        """Take one sample: time [s], fluxgate (3,) [nT], scalar [nT]. Returns the answered
        samples (zero or one).

        Raises
        ------
        AeromagError
            A time not after the previous sample's (the caller reports and skips it).
        """
        start = check_time(time_s, self._last_t, self.tl.checks.gap_s)
        self._last_t = time_s
        self._held.append(_Held(float(time_s), np.asarray(flux, float), float(scalar), start))
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
        out = [self._answer(i) for i in range(first, len(self._held))]
        self._held.clear()
        self._last_t = -np.inf
        return out

    def _check(self, i: int, has_next: bool) -> None:
        """Decide held sample ``i``'s flags (it needs its neighbours in its segment)."""
        h, checks = self._held[i], self.tl.checks
        prev = self._held[i - 1] if i > 0 and not h.start else None
        nxt = self._held[i + 1] if has_next and not self._held[i + 1].start else None
        h.flux_ok = checks.usable_one(
            self.tl.flux, h.b, None if prev is None else prev.b, None if nxt is None else nxt.b
        )
        h.scalar_ok = checks.usable_one(
            self.tl.scalar,
            np.array([h.s]),
            None if prev is None else np.array([prev.s]),
            None if nxt is None else np.array([nxt.s]),
        )

    def _answer(self, i: int) -> StreamOutput:
        """The output of held sample ``i`` (its flags and its neighbours' are known)."""
        h = self._held[i]
        if not h.flux_ok or not h.scalar_ok:
            what = "fluxgate" if not h.flux_ok else "scalar"
            return StreamOutput(h.t, None, f"{what} non-finite or a spike at t = {h.t:g} s")
        prev = self._held[i - 1] if i > 0 else None
        nxt = self._held[i + 1] if i + 1 < len(self._held) else None
        has_prev = prev is not None and bool(prev.flux_ok) and not h.start
        has_next = nxt is not None and bool(nxt.flux_ok) and not nxt.start
        if has_prev and has_next:
            db = (nxt.b - prev.b) / 2.0  # type: ignore[union-attr]
        elif has_next:
            db = nxt.b - h.b  # type: ignore[union-attr]
        elif has_prev:
            db = h.b - prev.b  # type: ignore[union-attr]
        else:
            return StreamOutput(h.t, None, f"fluxgate has no usable neighbour at t = {h.t:g} s")
        correction = tl_correction(self.tl, h.b[None, :], db[None, :])[0]
        return StreamOutput(h.t, (float(h.s - correction),))


def check_time(time_s: float, last_s: float, gap_s: float) -> bool:
    """Whether a stream's sample at ``time_s`` [s] starts a segment (the first, or after a step
    above ``gap_s``); :class:`~aeromag_env.errors.AeromagError` when it is not after the
    previous one at ``last_s`` (the caller reports and skips it)."""
    if not time_s > last_s:
        raise AeromagError(f"time {time_s!r} s is not after the previous sample's {last_s:g} s")
    return not (time_s - last_s <= gap_s)
