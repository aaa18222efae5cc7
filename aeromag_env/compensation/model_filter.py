"""Continue a calibrated recursive filter over another flight, whole or one sample at a time.

A Kalman-family model holds the filter as calibration left it (:class:`CalibratedFilter`: its
state, covariance, Q and R, and how many samples it had processed). :func:`filter_compensation`
continues it over a whole flight and :class:`FilterStream` over samples as they arrive; both
give the same numbers (tested to 1e-9 nT; they agree bit for bit) because every input of the
filter is computed the same way, sample by sample, from what has arrived:

* the Earth field: IGRF-14 from tangent planes at anchor points
  (:mod:`aeromag_env.geo.earth_tangent`, within 0.01 nT of IGRF at every sample), plus the
  ``diurnal`` channel along the main field when the flight has one, rotated into the body frame
  by the attitude (:func:`earth_body`);
* its rate: :func:`rate_rows` inside runs of known field within one segment (``backward``: the
  difference with the previous sample, the first of a run taking the next one's; ``central``:
  the centred difference, one-sided at a run's ends);
* the fluxgate, rotated into body axes by the calibration's mount, usable where the sample checks
  of :mod:`aeromag_env.compensation.model_checks` pass;
* the filter: the compiled loop (:func:`aeromag_env.compensation.kernels.advance`) continued from
  the calibrated state; a stream keeps its arrays in a window of :data:`STREAM_ROWS` rows and
  moves the last ``window`` samples (what the runaway check reads back) to the front when it is
  full (:meth:`FilterStream._rebase`), counting the samples moved past
  (``kernel_layout.INTS.base``), so memory is bounded and the adaptive rules see the same sample
  counts as on a whole flight.

A stream answers sample k once sample k + 1 has arrived (its spike test and, at a run's first
sample or with the ``central`` scheme, its rate look one sample ahead): 0.1 s at 10 Hz.
"""

from __future__ import annotations

import datetime as _dt
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np

from aeromag_env.compensation.compensate import Compensation, output_names
from aeromag_env.compensation.kalman import FilterState
from aeromag_env.compensation.kernel_layout import INTS
from aeromag_env.compensation.model import FilterConfig
from aeromag_env.compensation.model_apply import StreamOutput, check_time, segment_slices
from aeromag_env.compensation.model_checks import SampleChecks
from aeromag_env.compensation.model_drift import vector_residual
from aeromag_env.compensation.samples import flight_samples
from aeromag_env.flight.data import ATTITUDE_NAMES, Flight
from aeromag_env.geo.earth_tangent import TangentTrack, tangent_track
from aeromag_env.geo.frames import dcm_from_euler

#: Rows of a stream's filter arrays (the window moved to the front when they are full) [samples].
STREAM_ROWS = 4096


@dataclass(frozen=True)
class CalibratedFilter:
    """A recursive filter as calibration left it, and what continuing it needs.

    Attributes
    ----------
    cfg : FilterConfig
        The filter's settings (its ``method`` included).
    end : dict
        ``state`` (21,), ``covariance`` (21, 21), ``process_noise`` (21, Q's diagonal) and
        ``measurement_noise`` (3, 3, R), physical units.
    samples : int
        The samples the calibration's filter processed (Sage–Husa's fading counts on from it).
    rotation : (3, 3) or None
        The fluxgate's mount: body axes ``m_b = m_s R`` (None: sensor axes are body axes).
    flux : str
        The fluxgate prefix.
    checks : SampleChecks
        The sample checks fixed at calibration.
    sample_rate_hz : float
        The calibration's sample rate [Hz] (the recalibrate residual's band-pass).
    """

    cfg: FilterConfig
    end: dict[str, np.ndarray]
    samples: int
    rotation: np.ndarray | None
    flux: str
    checks: SampleChecks
    sample_rate_hz: float

    @property
    def output_names(self) -> tuple[str, ...]:
        """The compensated fluxgate's three channels, as ``compensate`` writes them."""
        return output_names(self.cfg.method, self.flux)[:3]

    def start(self, y: np.ndarray, t_b: np.ndarray, tdot_b: np.ndarray) -> FilterState:
        """A :class:`FilterState` over ``y``, ``t_b``, ``tdot_b`` (n, 3) that starts where the
        calibration ended: its state, covariance, Q and R in place of the configuration's
        initial ones, and its sample count. The innovation window starts empty."""
        state = FilterState(self.cfg, y, t_b, tdot_b, store_states=False)
        d = state.d
        state.z[:] = self.end["state"] / d  # the arrays are updated in place, never replaced
        state.z_good[:] = state.z
        state.p[:] = self.end["covariance"] / np.outer(d, d)
        state.qd[:] = self.end["process_noise"] / d**2
        state.rm[:] = self.end["measurement_noise"]
        state.ints[INTS.base] = self.samples
        return state


def to_body(m_sensor: np.ndarray, rotation: np.ndarray | None) -> np.ndarray:
    """Fluxgate rows (n, 3) in body axes: ``m_b = m_s R`` element by element (the same bits for
    one row as for many) [nT]."""
    if rotation is None:
        return np.array(m_sensor, dtype=float)
    m, r = m_sensor, rotation
    return np.column_stack(
        [m[:, 0] * r[0, i] + m[:, 1] * r[1, i] + m[:, 2] * r[2, i] for i in range(3)]
    )


def earth_body(t_n: np.ndarray, attitude_rad: np.ndarray, diurnal: np.ndarray | None) -> np.ndarray:
    """The model field in body axes (n, 3) [nT]: ``t_n`` (n, 3) NED [nT] plus ``diurnal`` (n,)
    [nT] along it, rotated by the attitude (n, 3) roll, pitch, yaw [rad] (``C_nbᵀ t_n``, element
    by element)."""
    if diurnal is not None:
        size = np.sqrt(t_n[:, 0] * t_n[:, 0] + t_n[:, 1] * t_n[:, 1] + t_n[:, 2] * t_n[:, 2])
        t_n = t_n + (t_n / size[:, None]) * diurnal[:, None]
    c = dcm_from_euler(attitude_rad[:, 0], attitude_rad[:, 1], attitude_rad[:, 2])
    return np.column_stack(
        [c[:, 0, i] * t_n[:, 0] + c[:, 1, i] * t_n[:, 1] + c[:, 2, i] * t_n[:, 2] for i in range(3)]
    )


def rate_rows(
    x: tuple[np.ndarray, np.ndarray, np.ndarray],
    t: tuple[np.ndarray, np.ndarray, np.ndarray],
    joined: tuple[np.ndarray, np.ndarray],
    scheme: str,
) -> np.ndarray:
    """The rate of each row of ``x[1]`` (n, 3) from its neighbours ``x[0]`` and ``x[2]`` (the rows
    before and after), their times ``t`` (n,) each [s], and ``joined`` (n,) each: whether the
    row before / after is in the same run of known field [x's unit per s]; NaN for a run of one.

    ``backward``: ``(x_k − x_{k−1}) / Δt``, the first of a run taking the next row's; ``central``:
    ``(x_{k+1} − x_{k−1}) / (t_{k+1} − t_{k−1})``, one-sided at a run's ends.
    """
    before, here, after = x
    t0, t1, t2 = t
    back, ahead = joined
    with np.errstate(invalid="ignore", divide="ignore"):
        backward = (here - before) / (t1 - t0)[:, None]
        forward = (after - here) / (t2 - t1)[:, None]
        central = (after - before) / (t2 - t0)[:, None]
    out = np.where(back[:, None], backward, np.where(ahead[:, None], forward, np.nan))
    if scheme == "central":
        out = np.where((back & ahead)[:, None], central, out)
    return out


@dataclass(frozen=True)
class FilterInputs:
    """The filter's inputs over a whole flight (module docstring), each (n, …).

    Attributes
    ----------
    meas : (n, 3) the fluxgate in body axes [nT]
    t_b, tdot_b : (n, 3) the model field in body axes [nT] and its rate [nT/s]
    flux_ok : (n,) bool, the fluxgate passed the sample checks
    starts : (n,) bool, a segment starts here
    """

    meas: np.ndarray
    t_b: np.ndarray
    tdot_b: np.ndarray
    flux_ok: np.ndarray
    starts: np.ndarray

    @property
    def y(self) -> np.ndarray:
        """``T_m − T`` (n, 3) [nT], NaN where the fluxgate is flagged."""
        return np.where(self.flux_ok[:, None], self.meas - self.t_b, np.nan)


def filter_inputs(cal: CalibratedFilter, flight: Flight, date: _dt.datetime) -> FilterInputs:
    """The filter's inputs over ``flight`` (the same numbers a :class:`FilterStream` computes)."""
    tt, flux = flight.tt, flight.vector(cal.flux)
    starts = cal.checks.starts(tt)
    lat, lon, alt = flight.position_rad()
    attitude = np.column_stack(flight.attitude_rad())
    diurnal = flight.fields.get("diurnal")
    t_b = earth_body(tangent_track(lat, lon, alt, date), attitude, diurnal)
    known = np.all(np.isfinite(t_b), axis=1)
    joined = np.zeros(tt.size, dtype=bool)  # row k − 1 in row k's run
    joined[1:] = known[1:] & known[:-1] & ~starts[1:]
    ahead = np.append(joined[1:], False)
    rows = (np.vstack([t_b[:1], t_b[:-1]]), t_b, np.vstack([t_b[1:], t_b[-1:]]))
    times = (np.append(tt[:1], tt[:-1]), tt, np.append(tt[1:], tt[-1:]))
    tdot_b = rate_rows(rows, times, (joined, ahead), cal.cfg.rate_scheme)
    return FilterInputs(
        meas=to_body(flux, cal.rotation),
        t_b=t_b,
        tdot_b=tdot_b,
        flux_ok=cal.checks.usable(cal.flux, flux, starts),
        starts=starts,
    )


def filter_compensation(
    cal: CalibratedFilter,
    flight: Flight,
    date: _dt.datetime,
    settings: dict[str, Any],
    mask: np.ndarray | None = None,
) -> Compensation:
    """The calibrated filter continued over ``flight`` (it keeps adapting), as a
    :class:`~aeromag_env.compensation.compensate.Compensation`, with ``settings`` and the
    recalibrate residual in ``settings["drift"]`` (measured on ``mask``, (n,) bool; None:
    every sample)."""
    inputs = filter_inputs(cal, flight, date)
    y = inputs.y
    state = cal.start(y, inputs.t_b, inputs.tdot_b)
    state.advance(state.n)
    res = state.result()
    known = np.all(np.isfinite(inputs.t_b) & np.isfinite(inputs.tdot_b), axis=1)
    est = np.where(known[:, None], res.interference, np.nan)
    after = np.where(inputs.flux_ok[:, None], inputs.meas - est, np.nan)
    y_drift = y if mask is None else np.where(mask[:, None], y, np.nan)
    parts = segment_slices(inputs.starts)
    drift = vector_residual(
        cal.end["state"], y_drift, inputs.t_b, inputs.tdot_b, inputs.meas, cal.sample_rate_hz, parts
    )
    samples = flight_samples(flight, [cal.flux, *ATTITUDE_NAMES], [])
    valid = inputs.flux_ok & known
    return Compensation(
        method=cal.cfg.method,
        settings={**settings, "drift": drift},
        coefficients={"state": res.final_state.tolist()},
        fields=dict(zip(output_names(cal.cfg.method, cal.flux), [*after.T, *est.T], strict=True)),
        total_before=np.linalg.norm(inputs.meas, axis=1),
        total_after=np.linalg.norm(after, axis=1),
        model_total=np.linalg.norm(inputs.t_b, axis=1),
        series={"ror": res.ror, "qoq": res.qoq, "q_scale": res.q_scale, "r_scale": res.r_scale},
        divergences=res.divergences,
        outliers_rejected=res.outliers_rejected,
        nonfinite=int(np.sum(~valid)),
        samples=_with(samples, valid, parts),
        filter_end={
            "state": res.final_state,
            "covariance": res.final_covariance,
            "process_noise": res.final_q,
            "measurement_noise": res.final_r,
            "samples": np.asarray(cal.samples + state.n),
        },
    )


def _with(samples: Any, valid: np.ndarray, segments: list[slice]) -> Any:
    from dataclasses import replace

    return replace(samples, valid=valid, segments=segments)


@dataclass
class _Sample:
    """A sample a filter stream holds: time [s], the raw fluxgate (3,) and in body axes (3,)
    [nT], the model field in body axes (3,) [nT], and whether it starts a segment and whether
    its field is known (finite)."""

    t: float
    raw: np.ndarray
    meas: np.ndarray
    t_b: np.ndarray
    start: bool
    known: bool


class FilterStream:
    """A calibrated filter continued over samples as they arrive (bounded memory).

    :meth:`update` takes one sample and returns the samples it can now answer (the previous
    one, or none yet); :meth:`flush` answers the last at the end. The answers equal
    :func:`filter_compensation` on the whole flight.

    Parameters
    ----------
    cal : CalibratedFilter
    date : datetime
        The flight's date (the Earth field's epoch).
    """

    def __init__(self, cal: CalibratedFilter, date: _dt.datetime) -> None:
        self.cal = cal
        self.earth = TangentTrack(date)
        zeros = np.zeros((STREAM_ROWS, 3))
        self.state = cal.start(zeros, zeros, zeros)
        self.state.ints[INTS.k] = 0
        self._keep = cal.cfg.window  # rows the runaway check reads back
        self._held: deque[_Sample] = deque(maxlen=3)
        self._last_t = -np.inf

    def update(
        self,
        time_s: float,
        position: tuple[float, float, float],
        attitude: tuple[float, float, float],
        flux: np.ndarray,
        diurnal: float | None = None,
    ) -> list[StreamOutput]:
        """Take one sample: time [s], position (lat [deg], lon [deg], height [m]), attitude
        (roll, pitch, yaw [deg]), fluxgate (3,) in its own axes [nT] and the base station's
        ``diurnal`` [nT] when the flight has one. Returns the answered samples (zero or one).

        Raises
        ------
        AeromagError
            A time not after the previous sample's (the caller reports and skips it).
        """
        start = check_time(time_s, self._last_t, self.cal.checks.gap_s)
        self._last_t = time_s
        self._held.append(self._sample(float(time_s), position, attitude, flux, diurnal, start))
        if len(self._held) < 2:
            return []
        return [self._answer(-2)]

    def flush(self) -> list[StreamOutput]:
        """Answer the sample still held (at the end of the stream)."""
        out = [self._answer(-1)] if self._held else []
        self._held.clear()
        self._last_t = -np.inf
        return out

    def _sample(
        self,
        t: float,
        position: tuple[float, float, float],
        attitude: tuple[float, float, float],
        flux: np.ndarray,
        diurnal: float | None,
        start: bool,
    ) -> _Sample:
        lat, lon = np.deg2rad(np.array(position[:2], float))
        t_n = self.earth.field(float(lat), float(lon), float(position[2]))[None, :]
        att = np.deg2rad(np.array([attitude], float))
        extra = None if diurnal is None else np.array([diurnal], float)
        t_b = earth_body(t_n, att, extra)
        raw = np.asarray(flux, float).reshape(1, 3)
        meas = to_body(raw, self.cal.rotation)
        return _Sample(t, raw[0], meas[0], t_b[0], start, bool(np.all(np.isfinite(t_b))))

    def _answer(self, i: int) -> StreamOutput:
        """Step the filter with held sample ``i`` (-2: the next one has come; -1: the last)."""
        held = list(self._held)
        here = held[i]
        prev = held[i - 1] if len(held) + i >= 1 else None
        nxt = held[i + 1] if i == -2 else None
        before = prev if prev is not None and not here.start else None
        after = nxt if nxt is not None and not nxt.start else None
        ok = self.cal.checks.usable_one(
            self.cal.flux,
            here.raw,
            None if before is None else before.raw,
            None if after is None else after.raw,
        )
        back = before is not None and here.known and before.known
        ahead = after is not None and here.known and after.known
        tdot = self._rate(here, before, after, back, ahead)
        y = here.meas - here.t_b if ok else np.full(3, np.nan)
        est = self._step(y, here.t_b, tdot)
        known = here.known and bool(np.all(np.isfinite(tdot)))
        if not (ok and known):
            what = "fluxgate non-finite or a spike" if not ok else "position or attitude unknown"
            return StreamOutput(here.t, None, f"{what} at t = {here.t:g} s")
        return StreamOutput(here.t, tuple(float(v) for v in here.meas - est))

    def _rate(
        self, here: _Sample, before: _Sample | None, after: _Sample | None, back: bool, ahead: bool
    ) -> np.ndarray:
        """:func:`rate_rows` of one sample (its neighbours in its segment, or itself)."""
        b, a = before or here, after or here
        rows = (b.t_b[None, :], here.t_b[None, :], a.t_b[None, :])
        times = (np.array([b.t]), np.array([here.t]), np.array([a.t]))
        return rate_rows(
            rows, times, (np.array([back]), np.array([ahead])), self.cal.cfg.rate_scheme
        )[0]

    def _step(self, y: np.ndarray, t_b: np.ndarray, tdot: np.ndarray) -> np.ndarray:
        """Run the filter over one sample; its a-priori interference estimate (3,) [nT]."""
        s = self.state
        if s.k == STREAM_ROWS:
            self._rebase()
        k = s.k
        finite = np.isfinite(y), np.isfinite(t_b), np.isfinite(tdot)
        s.y[k] = np.where(finite[0], y, 0.0)
        s.t[k] = np.where(finite[1], t_b, 0.0)
        s.td[k] = np.where(finite[2], tdot, 0.0)
        s.valid[k] = bool(np.all(finite[0] & finite[1] & finite[2]))
        s.advance(k + 1)
        return s.est[k]

    def _rebase(self) -> None:
        """Move the last ``window`` rows to the front (the runaway check reads them back) and
        count the rows moved past, so that the next sample has a row."""
        s, keep = self.state, self._keep
        moved = STREAM_ROWS - keep
        for rows in (s.y, s.t, s.td, s.valid, s.est, s.innov):
            rows[:keep] = rows[moved:]
        s.ints[INTS.k] = keep
        s.ints[INTS.base] += moved
