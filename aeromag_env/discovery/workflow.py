"""Discrepancy workflow: find where a measured flight and the model disagree, name the missing
effect, add it, and show the gap shrink on data the fit never saw (DESIGN.md, "Discrepancy
workflow").

Steps (:func:`discover`):

1. **Base model.** The model Earth field ``T`` (IGRF-14 along the track, rotated by the file's
   attitude, plus ``diurnal`` along the main field when the file has a base-station channel) and
   the 21 coefficients of paper eq. 5, fitted on the calibration part. The simulated fluxgate
   signal is ``T + T_p + A T + B Ṫ``; the residual is measured minus simulated.
2. **Noise model.** Per axis, white noise plus a first-order Gauss–Markov process (the fluxgate's
   coloured noise), fitted by maximum likelihood to the residual. Its Kalman innovations whiten
   the residual and every regressor (generalised least squares), so tests are not fooled by
   coloured noise — a naive F-test on the raw residual would be.
3. **Candidates.** Every effect of :mod:`aeromag_env.simulation.effects` builds its regressor
groups from the
   channels present (one group per auxiliary channel for ``onboard_current``). A group whose
   part outside the base regressors' span is below :data:`ABSORBED_FRACTION` of its variance is
   *absorbed* (Frisch–Waugh–Lovell) and never tested or named; effects marked ``absorbed_by``
   in the library (offset, scale, non-orthogonality, misalignment) are always such groups.
4. **Forward selection.** Each remaining group gets a partial F-test on the whitened problem; a
   group has evidence when it passes Holm's correction (``p < α / m`` with m groups left) *and*
   its ΔBIC is positive (:func:`_significant`); the best by ΔBIC among those is added, and the
   search repeats until none has evidence. The F-test alone keeps a fixed false-inclusion rate
   per flight (about α) and trusts the fitted noise model, whose slow part a 20-min calibration
   under-states; the BIC penalty, ``log(rows)`` per regressor, grows with the data and asks a
   3-regressor group for F > 10 rather than F > 6. Groups that differ only in a non-linear
   parameter (the eddy time constant, the lag) are profiled: the best grid value competes with
   one more degree of freedom, and is refined between its grid neighbours once it enters. After
   each entry the noise model is re-fitted; its coloured part may shrink only where the entered
   group cannot have absorbed it (:func:`_ratchet`). A chosen ``sensor_lag`` shifts the whole
   modelled signal — Earth field, base aircraft field and the other named additive effects — not
   the Earth field alone (:func:`_lag_on_signal`): a lag also delays the aircraft's eddy field,
   ``−τ B T̈``, which is exactly the signature of ``eddy_time_constant``; with the Earth field
   alone shifted, that remainder let ``eddy_time_constant`` follow a true lag. A backward pass
   then drops any named effect without evidence (same rule, Holm over the named ones) given
   all the others.
5. **Gap.** Base and augmented models predict the held-out part; the gap is the RMS of measured
   minus simulated there above the white-noise floor, ``sqrt(RMS² − σ_w²)`` with ``σ_w`` from the
   final noise model (the sensor's white noise is no model gap; the raw RMS is reported too).

The held-out part is, by default, every third 60-s block (interleaved: a slowly varying field is
interpolated, not extrapolated); with ``calibration_window`` it is everything outside that window.
Gaps in time (a step over 1.5× the median interval) split the flight: samples within
:data:`GAP_GUARD_SAMPLES` of a gap are dropped (their derivatives straddle it) and the noise
model bridges it (the FOGM state is propagated over the missing time, as over held-out
blocks). Non-finite samples are dropped and counted.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import ATTITUDE_NAMES, Flight, vector_names
from aeromag_env.simulation.effects import EFFECTS, EffectContext, Group, SensorLag

#: Family-wise false-alarm level of the effect tests (Holm-corrected over candidate groups).
ALPHA = 0.01
#: A group with less of its variance outside the base span than this is absorbed.
ABSORBED_FRACTION = 1e-3
#: Length of the interleaved blocks [s]; every third block is held out.
BLOCK_S = 60.0
#: Minimum calibration data [s].
MIN_CALIBRATION_S = 300.0
#: Minimum held-out data [s].
MIN_HELD_OUT_S = 60.0
#: Samples dropped on each side of a time gap.
GAP_GUARD_SAMPLES = 2
#: Forward-selection steps at most.
MAX_EFFECTS = 5
#: An entered group that could absorb less than this share of the coloured noise's variance
#: (per axis) cannot be why the re-fitted coloured part shrank: the re-fit stands.
ABSORBABLE_SHARE = 0.05
#: A group needs ΔBIC above this (besides the Holm-corrected F-test) to enter or to stay.
MIN_DELTA_BIC = 0.0
#: Alternations of the joint fit and the shifted modelled signal of a chosen sensor_lag.
LAG_SIGNAL_ITERATIONS = 3
_BASE_LABELS = ("T_p", "A_x", "A_y", "A_z", "B_x", "B_y", "B_z")


# --------------------------------------------------------------------------- noise model


@dataclass(frozen=True)
class NoiseModel:
    """White noise plus a first-order Gauss–Markov process, per axis (arrays of 3)."""

    white_std_nt: np.ndarray
    fogm_std_nt: np.ndarray
    fogm_tau_s: np.ndarray

    def to_dict(self) -> dict[str, list[float]]:
        return {
            k: [float(v) for v in getattr(self, k)]
            for k in ("white_std_nt", "fogm_std_nt", "fogm_tau_s")
        }


@njit(cache=True)
def _innovations(
    x: np.ndarray, gap: np.ndarray, tau: float, fogm_var: float, white_var: float, out: np.ndarray
) -> float:
    """Normalised Kalman innovations of columns ``x`` (m, c) under ``y = f + w``: ``f`` a FOGM of
    variance ``fogm_var`` and correlation time ``tau``, ``w`` white of variance ``white_var``.

    ``gap[k]`` is the time since the previous row [s] (``inf``: independent restart), so rows
    left out (held-out blocks) or lost (time gaps) are bridged exactly: the FOGM state is
    propagated across them. The gains do not depend on the data, so one pass whitens every
    column; returns the Gaussian log-likelihood of column 0.
    """
    m, c = x.shape
    f = np.zeros(c)
    p = fogm_var
    ll = 0.0
    for k in range(m):
        a = math.exp(-gap[k] / tau)
        f *= a
        p = a * a * p + fogm_var * (1.0 - a * a)
        s = p + white_var
        g = p / s
        rs = 1.0 / math.sqrt(s)
        for j in range(c):
            v = x[k, j] - f[j]
            out[k, j] = v * rs
            f[j] += g * v
        v0 = out[k, 0]
        ll -= 0.5 * (math.log(2.0 * math.pi * s) + v0 * v0)
        p = (1.0 - g) * p
    return ll


@njit(cache=True)
def _fogm_quadratic(q: np.ndarray, gap: np.ndarray, tau: float) -> np.ndarray:
    """``q_jᵀ K q_j`` for each column of ``q`` (m, c), with ``K_kl = exp(−|t_k − t_l| / τ)`` the
    correlation of a unit FOGM over rows ``gap`` apart (as in :func:`_innovations`).

    One forward pass: ``qᵀ K q = 2 Σ_k q_k F_k − Σ_k q_k²`` with ``F_k = q_k + a_k F_{k−1}``,
    ``a_k = exp(−gap[k] / τ)`` (``F_k = Σ_{l≤k} K_kl q_l``).
    """
    m, c = q.shape
    out = np.zeros(c)
    for j in range(c):
        f = 0.0
        for k in range(m):
            f = q[k, j] + math.exp(-gap[k] / tau) * f
            out[j] += (2.0 * f - q[k, j]) * q[k, j]
    return out


def whiten(x: np.ndarray, gap: np.ndarray, white: float, fogm: float, tau: float) -> np.ndarray:
    """Whitened copy of ``x`` (m, c) under the white + FOGM noise model (one axis)."""
    out = np.empty_like(x)
    _innovations(np.ascontiguousarray(x), gap, tau, fogm * fogm, white * white, out)
    return out


def fit_noise(r: np.ndarray, gap: np.ndarray) -> NoiseModel:
    """Maximum-likelihood white + FOGM model of each column of the residual ``r`` (m, 3)."""
    fits = [_fit_one(np.ascontiguousarray(r[:, i : i + 1]), gap) for i in range(3)]
    white, fogm, tau = (np.array(v) for v in zip(*fits, strict=True))
    return NoiseModel(white, fogm, tau)


def _fit_one(col: np.ndarray, gap: np.ndarray) -> tuple[float, float, float]:
    """Maximum-likelihood (white std, FOGM std, FOGM τ) of one residual column (m, 1); Nelder–Mead
    in log parameters from a 60-s and a 600-s start, the better kept."""
    from scipy.optimize import minimize

    buf = np.empty_like(col)
    sd = float(np.std(col)) or 1.0
    w0 = max(float(np.std(np.diff(col[:, 0]))) / math.sqrt(2.0), 1e-3 * sd)  # from differences
    f0 = max(math.sqrt(max(sd * sd - w0 * w0, 0.0)), 1e-2 * sd)

    def nll(z: np.ndarray) -> float:
        w, f, t = np.exp(z)
        return -_innovations(col, gap, t, f * f, w * w, buf)

    opts = {"xatol": 1e-2, "fatol": 1e-2, "maxiter": 200}
    runs = [
        minimize(nll, np.log([w0, f0, t0]), method="Nelder-Mead", options=opts)
        for t0 in (60.0, 600.0)
    ]
    w, f, t = np.exp(min(runs, key=lambda res: res.fun).x)
    return float(w), float(f), float(min(t, 1e6))


def ljung_box(x: np.ndarray, lags: int = 20) -> tuple[float, float]:
    """Ljung–Box statistic and p-value of a series (mean removed)."""
    from scipy.stats import chi2

    x = np.asarray(x, float) - np.mean(x)
    n = x.size
    den = float(np.dot(x, x))
    rho = np.array([np.dot(x[:-k], x[k:]) / den for k in range(1, lags + 1)])
    q = float(n * (n + 2) * np.sum(rho**2 / (n - np.arange(1, lags + 1))))
    return q, float(chi2.sf(q, lags))


# --------------------------------------------------------------------------- data preparation


@dataclass
class _Data:
    ctx: EffectContext
    y: np.ndarray  # (n, 3) measured minus model Earth field
    usable: np.ndarray
    calibration: np.ndarray
    held_out: np.ndarray
    dt: float
    scheme: str
    n_gaps: int
    n_nonfinite: int


def _prepare(flight: Flight, flux: str, calibration_window: tuple[float, float] | None) -> _Data:
    from aeromag_env.compensation.compensate import earth_model_ned
    from aeromag_env.geo.frames import dcm_from_euler, nav_to_body, time_derivative

    missing = [nm for nm in (*vector_names(flux), *ATTITUDE_NAMES) if nm not in flight]
    if any(nm in missing for nm in ATTITUDE_NAMES):
        raise AeromagError(
            "discovery needs the attitude (ins_roll, ins_pitch, ins_yaw) to rotate the Earth "
            "field into body axes; the file lacks "
            + ", ".join(nm for nm in missing if nm.startswith("ins_"))
        )
    if missing:
        have = ", ".join(flight.fluxgates()) or "none"
        raise AeromagError(f"no fluxgate {flux} in the file (fluxgates present: {have})")
    try:
        t_n = earth_model_ned(flight)
    except KeyError as e:
        raise AeromagError(
            f"discovery needs position and date for the Earth field: {e.args[0]}"
        ) from None
    tt = flight.tt
    if flight.n < 10:
        raise AeromagError(f"the flight has only {flight.n} samples")
    step = np.diff(tt)
    dt = float(np.median(step))
    gap_after = np.flatnonzero(step > 1.5 * dt)  # a gap between sample k and k + 1
    c_nb = dcm_from_euler(*flight.attitude_rad())
    t_b = nav_to_body(c_nb, t_n)
    tdot = time_derivative(t_b, tt, "central")
    t2dot = time_derivative(tdot, tt, "central")
    alt_name = flight.altitude_name()
    alt = flight[alt_name] if alt_name else np.full(flight.n, np.nan)
    y = flight.vector(flux) - t_b
    usable = np.all(np.isfinite(y) & np.isfinite(tdot) & np.isfinite(t2dot), axis=1)
    n_nonfinite = int(np.sum(~usable))
    for g in gap_after:
        usable[max(0, g - GAP_GUARD_SAMPLES + 1) : g + 1 + GAP_GUARD_SAMPLES] = False
    usable[:GAP_GUARD_SAMPLES] = usable[-GAP_GUARD_SAMPLES:] = False
    if calibration_window is None:
        block = np.floor((tt - tt[0]) / BLOCK_S).astype(int)
        calibration = usable & (block % 3 != 2)
        scheme = f"interleaved {BLOCK_S:g} s blocks: every third block held out"
    else:
        t0, t1 = calibration_window
        if not (t0 < t1):
            raise AeromagError(f"--calibration-window needs T0 < T1 [s], got {t0} {t1}")
        calibration = usable & (tt >= t0) & (tt <= t1)
        scheme = f"calibration window {t0:g}–{t1:g} s; held out: the rest of the flight"
    held_out = usable & ~calibration
    cal_s, held_s = calibration.sum() * dt, held_out.sum() * dt
    if cal_s < MIN_CALIBRATION_S:
        raise AeromagError(
            f"the calibration part has {cal_s:.0f} s of usable data; discovery needs at least "
            f"{MIN_CALIBRATION_S:.0f} s (21 base coefficients per axis; slow effects need minutes)"
        )
    if held_s < MIN_HELD_OUT_S:
        raise AeromagError(
            f"only {held_s:.0f} s of usable data lie outside the calibration part; the gap is "
            f"scored on held-out data and needs at least {MIN_HELD_OUT_S:.0f} s"
        )
    aux = {nm: np.nan_to_num(flight[nm]) for nm in flight.aux_channels()}
    ctx = EffectContext(tt=tt, c_nb=c_nb, t_b=t_b, tdot_b=tdot, t2dot_b=t2dot, alt=alt, aux=aux)
    return _Data(
        ctx, y, usable, calibration, held_out, dt, scheme, int(gap_after.size), n_nonfinite
    )


def base_columns(t_b: np.ndarray, tdot_b: np.ndarray) -> np.ndarray:
    """The 21 base regressors as vector columns (n, 3, 21), axis-major ``[1, T, Ṫ]`` per axis."""
    n = t_b.shape[0]
    cols = np.zeros((n, 3, 3, 7))
    rows = np.column_stack([np.ones(n), t_b, tdot_b])
    for i in range(3):
        cols[:, i, i, :] = rows
    return cols.reshape(n, 3, 21)


def base_state(beta: np.ndarray) -> np.ndarray:
    """Axis-major base coefficients (21) → state ``[T_p, A row-major, B row-major]``."""
    b = np.asarray(beta[:21]).reshape(3, 7)
    return np.r_[b[:, 0], b[:, 1:4].ravel(), b[:, 4:7].ravel()]


# --------------------------------------------------------------------------- the linear problem


def _stack(x: np.ndarray) -> np.ndarray:
    """Vector columns (m, 3, p) → axis-stacked rows (3m, p)."""
    return x.transpose(1, 0, 2).reshape(-1, x.shape[2])


def _orthonormal(x: np.ndarray, tol: float = 1e-7) -> np.ndarray:
    """Orthonormal basis of the column space of ``x`` (rank by singular values > tol·max)."""
    if x.shape[1] == 0:
        return x
    u, s, _ = np.linalg.svd(x / np.maximum(np.linalg.norm(x, axis=0), 1e-300), full_matrices=False)
    return u[:, s > tol * s[0]] if s.size and s[0] > 0 else u[:, :0]


class _Problem:
    """The whitened, axis-stacked least-squares problem on the calibration rows.

    After :meth:`set_noise`, the base regressors are projected out of the whitened data and of
    every candidate once (Frisch–Waugh–Lovell); tests then work on those small residual problems.
    """

    def __init__(self, data: _Data, columns: list[np.ndarray]) -> None:
        self.data = data
        self.idx = np.flatnonzero(data.calibration)
        self.gap = np.r_[np.inf, np.diff(data.ctx.tt[self.idx])]
        self.y = data.y[self.idx]
        self.columns = [c[self.idx] for c in columns]  # each (m, 3, p); 0 is the base
        self.noise: NoiseModel | None = None
        self.white: list[np.ndarray] = []
        self.yw = np.empty(0)
        self.r0 = np.empty(0)
        self.perp: list[np.ndarray] = []
        self._spans: dict[tuple[int, ...], tuple[np.ndarray, np.ndarray]] = {}

    def set_noise(self, noise: NoiseModel) -> None:
        self.noise = noise
        self.yw = self._whiten_columns(self.y[:, :, None])[:, 0]
        allc = self._whiten_columns(np.concatenate(self.columns, axis=2))
        edges = np.cumsum([0] + [c.shape[2] for c in self.columns])
        self.white = [allc[:, edges[j] : edges[j + 1]] for j in range(len(self.columns))]
        self._q0 = _orthonormal(self.white[0])
        self.r0 = self._off_base(self.yw)
        self.perp = [self._off_base(w) for w in self.white]
        self.k0 = self._q0.shape[1]
        self._spans = {}

    def add(self, columns: np.ndarray) -> int:
        """Append a candidate (n, 3, p) built after :meth:`set_noise`; returns its index."""
        self.columns.append(columns[self.idx])
        w = self._whiten_columns(self.columns[-1])
        self.white.append(w)
        self.perp.append(self._off_base(w))
        return len(self.columns) - 1

    def replace(self, index: int, columns: np.ndarray) -> None:
        """Rebuild candidate ``index`` from new columns (n, 3, p), under the current noise."""
        self.columns[index] = columns[self.idx]
        self.white[index] = self._whiten_columns(self.columns[index])
        self.perp[index] = self._off_base(self.white[index])
        self._spans = {}

    def _off_base(self, x: np.ndarray) -> np.ndarray:
        return x - self._q0 @ (self._q0.T @ x)

    def _whiten_columns(self, cols: np.ndarray) -> np.ndarray:
        """Whitened, axis-stacked copy (3m, p) of calibration-row columns (m, 3, p)."""
        noise = self.noise
        assert noise is not None
        m = self.idx.size
        out = np.empty((3 * m, cols.shape[2]))
        for i in range(3):
            out[i * m : (i + 1) * m] = whiten(
                cols[:, i, :],
                self.gap,
                noise.white_std_nt[i],
                noise.fogm_std_nt[i],
                noise.fogm_tau_s[i],
            )
        return out

    def _span(self, chosen: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """Orthonormal basis of the chosen effects (off the base) and the residual off it;
        cached per noise model, since every candidate of a step is tested against it."""
        key = tuple(chosen)
        if key not in self._spans:
            extra = [self.perp[j] for j in chosen if j != 0]
            q = (
                _orthonormal(np.concatenate(extra, axis=1))
                if extra
                else np.zeros((self.yw.size, 0))
            )
            self._spans[key] = (q, self.r0 - q @ (q.T @ self.r0))
        return self._spans[key]

    def whitened_residual(self, chosen: list[int]) -> np.ndarray:
        return self._span(chosen)[1]

    def fit(self, chosen: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """GLS coefficients of ``chosen`` (base first) and their covariance."""
        x = np.concatenate([self.white[j] for j in chosen], axis=1)
        norm = np.maximum(np.linalg.norm(x, axis=0), 1e-300)
        beta_s, *_ = np.linalg.lstsq(x / norm, self.yw, rcond=None)
        beta = beta_s / norm
        rss = float(np.sum((self.yw - x @ beta) ** 2))
        dof = x.shape[0] - x.shape[1]
        cov = np.linalg.pinv((x / norm).T @ (x / norm)) / np.outer(norm, norm) * (rss / dof)
        return beta, cov

    def residual(self, chosen: list[int], beta: np.ndarray) -> np.ndarray:
        """Un-whitened calibration residual (m, 3) of ``chosen`` with ``beta``."""
        x = np.concatenate([self.columns[j] for j in chosen], axis=2)
        return self.y - np.einsum("kip,p->ki", x, beta)

    def absorbable_share(self, chosen: list[int], candidate: int, tau_s: np.ndarray) -> np.ndarray:
        """Per axis, the share of a FOGM's variance that ``candidate``'s columns outside the span
        of ``chosen`` could absorb, for each row of correlation times ``tau_s`` (k, 3) → (k, 3).

        Notes
        -----
        With ``q_j`` an orthonormal basis of the candidate's columns off the chosen ones
        (un-whitened, axis-stacked) and ``e`` a unit FOGM on axis i, least squares removes
        ``E‖P e‖² = Σ_j q_jiᵀ K_i q_ji`` of ``E‖e‖² = m``. Columns on the time scale of the
        eddy or lag effects (T̈-like) absorb next to nothing of a slow FOGM; slow, flexible
        groups (the external-field splines) absorb much of it.
        """
        x = _stack(self.columns[candidate])
        q0 = _orthonormal(_stack(np.concatenate([self.columns[j] for j in chosen], axis=2)))
        xp = (x - q0 @ (q0.T @ x)) / np.maximum(np.linalg.norm(x, axis=0), 1e-300)
        u, s, _ = np.linalg.svd(xp, full_matrices=False)
        m = self.idx.size
        q = [np.ascontiguousarray(u[i * m : (i + 1) * m, s > 1e-6]) for i in range(3)]
        return np.array(
            [[_fogm_quadratic(q[i], self.gap, t).sum() / m for i, t in enumerate(row)]
             for row in np.atleast_2d(tau_s)]
        )  # fmt: skip

    def test_columns(self, chosen: list[int], columns: np.ndarray) -> dict[str, float] | None:
        """:meth:`test` for columns (n, 3, p) not in the problem."""
        idx = self.add(columns)
        try:
            return self.test(chosen, idx)
        finally:
            del self.columns[idx], self.white[idx], self.perp[idx]

    def test(self, chosen: list[int], candidate: int) -> dict[str, float] | None:
        """Residual sums for adding ``candidate`` to ``chosen`` (None: nothing identifiable)."""
        q, r = self._span(chosen)
        g = self.perp[candidate]
        g = g - q @ (q.T @ g)
        scale = float(np.linalg.norm(self.white[candidate], axis=0).max())
        u, s, _ = np.linalg.svd(g, full_matrices=False)
        keep = s > 1e-6 * scale
        p = int(keep.sum())
        if p == 0:
            return None
        rss0 = float(r @ r)
        drss = float(np.sum((u[:, keep].T @ r) ** 2))
        resid_dof = r.size - self.k0 - q.shape[1] - p
        return {"drss": drss, "rss0": rss0, "dof": p, "resid_dof": resid_dof, "rows": r.size}


def _statistics(t: dict[str, float], extra_dof: int) -> dict[str, float]:
    """F-test, ΔBIC and explained share of one candidate (``extra_dof`` profiled parameters)."""
    from scipy.stats import f as f_dist

    p = int(t["dof"]) + extra_dof
    dof = int(t["resid_dof"]) - extra_dof
    sigma2 = (t["rss0"] - t["drss"]) / dof
    fstat = (t["drss"] / p) / sigma2
    return {
        "f_statistic": fstat,
        "dof": p,
        "p_value": float(f_dist.sf(fstat, p, dof)),
        "log10_p_value": max(float(f_dist.logsf(fstat, p, dof) / math.log(10.0)), -300.0),
        "delta_bic": t["drss"] / sigma2 - p * math.log(t["rows"]),
        "explained_fraction": t["drss"] / t["rss0"],
    }


def _significant(stats: dict[str, float], threshold: float) -> bool:
    """Evidence for a group: its F-test passes the (Holm) ``threshold`` and its ΔBIC exceeds
    :data:`MIN_DELTA_BIC`.

    Notes
    -----
    ``ΔBIC = ΔRSS/σ² − p log(rows) > 0`` is ``F > log(rows)`` (about 10.5 on a 20-min, 10-Hz
    calibration, three axes): a Bayes factor for the group (Schwarz's approximation). Its
    false-inclusion rate falls as the flight grows, where a fixed α would name a spurious group
    in about α of all flights — over hundreds of flights, decoy channels among them; and it
    leaves a margin for the fitted noise model, whose slow part a short calibration under-
    states (the whitened residual keeps slow power, and slow channels then look significant).
    """
    return stats["p_value"] < threshold and stats["delta_bic"] > MIN_DELTA_BIC


def _best_of_families(
    groups: list[Group], tests: dict[int, dict[str, float] | None]
) -> dict[int, dict[str, float]]:
    """One test per family (effect and channel): the best member by ΔRSS, with one more degree
    of freedom when the family profiles a non-linear parameter."""
    best: dict[str, int] = {}
    size: dict[str, int] = {}
    for j, t in tests.items():
        if t is None:
            continue
        fam = groups[j - 1].family
        size[fam] = size.get(fam, 0) + 1
        if fam not in best or t["drss"] > tests[best[fam]]["drss"]:  # type: ignore[index]
            best[fam] = j
    return {j: _statistics(tests[j], int(size[fam] > 1)) for fam, j in best.items()}  # type: ignore[arg-type]


class BaseSpan:
    """Projector off the un-whitened base regressors on the calibration rows."""

    def __init__(self, base: np.ndarray, rows: np.ndarray) -> None:
        self.rows = rows
        self.q = _orthonormal(_stack(base[rows]), tol=1e-10)

    def perp(self, x: np.ndarray) -> np.ndarray:
        xs = _stack(x[self.rows])
        return xs - self.q @ (self.q.T @ xs)

    def identifiable_fraction(self, group: np.ndarray) -> float:
        """Share of the group's centred variance outside the base span, mean over its columns
        (0 when the group does not vary)."""
        g = group[self.rows]
        gc = _stack(g - g.mean(axis=0, keepdims=True))
        norms = np.linalg.norm(gc, axis=0)
        ok = norms > 1e-9 * max(float(np.linalg.norm(_stack(g), axis=0).max()), 1e-300)
        if not ok.any():
            return 0.0
        perp = self.perp(group[:, :, ok])
        return float(np.mean(np.sum(perp**2, axis=0) / norms[ok] ** 2))


# --------------------------------------------------------------------------- the workflow


@dataclass
class Discovery:
    """Result of :func:`discover`: the report (JSON-ready), the augmented model and series."""

    report: dict[str, Any]
    model: Any  # SimulationConfig
    series: dict[str, np.ndarray] = field(default_factory=dict)


def discover(
    flight: Flight,
    *,
    flux: str = "flux_a",
    calibration_window: tuple[float, float] | None = None,
    alpha: float = ALPHA,
    progress: Callable[[str], None] | None = None,
) -> Discovery:
    """Run the discrepancy workflow on one flight (real or simulated; ``truth_*`` is never read).

    Returns
    -------
    Discovery
        ``report`` has ``missing_effects`` (name, channel, evidence, parameters), ``gap``
        (held-out RMS before/after), ``candidates`` (every group's verdict), ``skipped``,
        ``diagnostics`` and ``data``; ``model`` is the augmented model as a
        :class:`~aeromag_env.simulation.config.SimulationConfig`.
    """
    if not 0 < alpha < 1:
        raise AeromagError(f"alpha must be in (0, 1), got {alpha}")
    say = progress or (lambda _msg: None)
    say("model field")
    data = _prepare(flight, flux, calibration_window)
    ctx = data.ctx
    base = base_columns(ctx.t_b, ctx.tdot_b)
    span = BaseSpan(base, data.calibration)
    groups: list[Group] = []
    fractions: list[float] = []
    skipped: list[dict[str, str]] = []
    absorbed: list[dict[str, Any]] = []
    for name, eff in EFFECTS.items():
        found, why = eff.groups(ctx)
        if why:
            skipped.append({"name": name, "reason": why})
        for g in found:
            frac = span.identifiable_fraction(g.columns)
            if eff.absorbed_by or frac < ABSORBED_FRACTION:
                absorbed.append(
                    {
                        "name": name,
                        "channel": g.channel,
                        "identifiable_fraction": frac,
                        "absorbed_by": eff.absorbed_by or "the base model here",
                    }
                )
            else:
                groups.append(g)
                fractions.append(frac)
    say("noise model")
    prob = _Problem(data, [base] + [g.columns for g in groups])
    chosen = [0]
    beta0 = _ols(prob, chosen)
    noise_before = fit_noise(prob.residual(chosen, beta0), prob.gap)
    prob.set_noise(noise_before)
    lb_before = ljung_box(prob.whitened_residual(chosen))
    beta_base, _ = prob.fit(chosen)
    steps: list[dict[str, Any]] = []
    evidence: dict[int, dict[str, Any]] = {}
    remaining = list(range(1, len(prob.columns)))
    while remaining and len(chosen) - 1 < MAX_EFFECTS:
        say(f"testing {len(remaining)} candidate groups")
        live = _best_of_families(groups, {j: prob.test(chosen, j) for j in remaining})
        m = len(live)
        passing = {j: t for j, t in live.items() if _significant(t, alpha / m)}
        steps.append(
            {
                "step": len(steps) + 1,
                "tests": {groups[j - 1].family: _round(t) for j, t in live.items()},
                "holm_threshold": alpha / max(m, 1),
            }
        )
        if not passing:
            break
        best = max(passing, key=lambda j: passing[j]["delta_bic"])
        stats = passing[best]
        if groups[best - 1].rebuild is not None:
            best, stats = _refine(prob, groups, fractions, chosen, best, stats)
        evidence[best] = {**stats, "holm_threshold": alpha / m, "step": len(steps)}
        chosen.append(best)
        remaining = [j for j in remaining if groups[j - 1].family != groups[best - 1].family]
        _lag_on_signal(prob, groups, chosen, base, ctx, evidence)
        steps[-1]["noise_model"] = _renoise(prob, chosen)
    chosen, retracted = _backward(prob, groups, chosen, alpha)
    _lag_on_signal(prob, groups, chosen, base, ctx, evidence)
    beta, cov = prob.fit(chosen)
    lb_after = ljung_box(prob.whitened_residual(chosen))
    noise_after = (
        fit_noise(prob.residual(chosen, beta), prob.gap) if len(chosen) > 1 else noise_before
    )

    say("gap")
    full = [base] + [g.columns for g in groups]
    pred_before = np.einsum("kip,p->ki", base, beta_base)
    pred_after = np.einsum("kip,p->ki", np.concatenate([full[j] for j in chosen], axis=2), beta)
    white = float(np.sqrt(np.mean(noise_after.white_std_nt**2)))
    gap, res_before, res_after = _gap(data, pred_before, pred_after, white)

    missing = []
    offset = 21
    for j in chosen[1:]:
        g = groups[j - 1]
        p = g.columns.shape[2]
        b, se = beta[offset : offset + p], np.sqrt(np.diag(cov)[offset : offset + p])
        offset += p
        effect_field = np.einsum("kip,p->ki", g.columns, b)
        missing.append(
            {
                "name": g.effect,
                "channel": g.channel,
                "evidence": {
                    **_round(evidence[j]),
                    "held_out_rms_nt": _rms(effect_field[data.held_out]),
                },
                "parameters": g.to_parameters(b),
                "standard_errors": dict(zip(g.labels, np.round(se, 12).tolist(), strict=True)),
                "physical": _physical(g, b, se),
            }
        )
    candidates = []
    last = steps[-1]["tests"] if steps else {}
    for fam in dict.fromkeys(g.family for g in groups):
        members = [j for j, g in enumerate(groups) if g.family == fam]
        pick = next((j for j in members if j + 1 in chosen or j + 1 in retracted), members[0])
        g = groups[pick]
        candidates.append(
            {
                "name": g.effect,
                "channel": g.channel,
                "regressors": len(g.labels),
                "profiled_values": len(members) if len(members) > 1 else None,
                "identifiable_fraction": fractions[pick],
                "verdict": "added"
                if pick + 1 in chosen
                else "retracted"
                if pick + 1 in retracted
                else "not significant",
                "last_test": next((t for k, t in last.items() if k == fam), None),
            }
        )
    candidates += [{**a, "verdict": "absorbed"} for a in absorbed]
    model = _model_config(flight, flux, base_state(beta), noise_after, missing)
    diagnostics = _diagnostics(
        data, span, res_before, noise_before, noise_after, lb_before, lb_after
    )
    report = {
        "missing_effects": [
            {k: e[k] for k in ("name", "channel", "evidence", "parameters")}
            | {"standard_errors": e["standard_errors"], "physical": e["physical"]}
            for e in missing
        ],
        "gap": gap,
        "verdict": (
            "nothing significant is missing"
            if not missing
            else "missing: " + ", ".join(groups[j - 1].family for j in chosen[1:])
        ),
        "candidates": candidates,
        "skipped": skipped,
        "selection": {
            "alpha": alpha,
            "correction": "Holm over candidate groups at each step",
            "criterion": (
                "partial F-test on GLS-whitened residuals below the Holm threshold and "
                f"ΔBIC > {MIN_DELTA_BIC:g}; best ΔBIC enters; backward: each named effect "
                "must meet the same rule given all the others"
            ),
            "sensor_lag_model": (
                "the whole modelled signal (Earth field, base aircraft field, other named "
                "additive effects) shifted by the lag, so the lag's shift of the aircraft eddy "
                "field is not left for eddy_time_constant"
            ),
            "steps": steps,
            "retracted": [groups[j - 1].family for j in retracted],
        },
        "diagnostics": diagnostics,
        "base_model": {
            "coefficients": _base_dict(base_state(beta_base)),
            "augmented_coefficients": _base_dict(base_state(beta)),
        },
        "data": {
            "samples": flight.n,
            "usable": int(data.usable.sum()),
            "calibration_samples": int(data.calibration.sum()),
            "held_out_samples": int(data.held_out.sum()),
            "held_out_scheme": data.scheme,
            "time_gaps": data.n_gaps,
            "nonfinite_samples_dropped": data.n_nonfinite,
            "flux": flux,
            "sample_interval_s": data.dt,
        },
    }
    series = {
        "tt": ctx.tt,
        "residual_before": res_before,
        "residual_after": res_after,
        "held_out": data.held_out,
    }
    return Discovery(report=report, model=model, series=series)


def _ols(prob: _Problem, chosen: list[int]) -> np.ndarray:
    x = np.concatenate([prob.columns[j] for j in chosen], axis=2)
    a = x.transpose(1, 0, 2).reshape(-1, x.shape[2])
    beta, *_ = np.linalg.lstsq(a, prob.y.T.reshape(-1), rcond=None)
    return np.asarray(beta)


def _renoise(prob: _Problem, chosen: list[int]) -> dict[str, Any]:
    """Re-fit the noise model after ``chosen[-1]`` entered and set it (through :func:`_ratchet`);
    returns what was done, for the report."""
    old = prob.noise
    assert old is not None
    b, _ = prob.fit(chosen)
    new = fit_noise(prob.residual(chosen, b), prob.gap)
    taus = np.array([old.fogm_tau_s, new.fogm_tau_s])
    share = prob.absorbable_share(chosen[:-1], chosen[-1], taus).max(axis=0)
    noise, kept = _ratchet(old, new, share)
    prob.set_noise(noise)
    return {
        "absorbable_share": np.round(share, 6).tolist(),
        "coloured_part_kept": kept.tolist(),
        **noise.to_dict(),
    }


def _ratchet(old: NoiseModel, new: NoiseModel, share: np.ndarray) -> tuple[NoiseModel, np.ndarray]:
    """Noise model after an effect entered, and the axes (3,) whose coloured part was kept.

    The re-fit's white part always; its coloured part too, except that it does not shrink
    (per axis, the larger FOGM of the two, with its correlation time) where the entered group
    could absorb at least :data:`ABSORBABLE_SHARE` of the coloured noise (``share``, per axis,
    from :meth:`_Problem.absorbable_share`): a slow, flexible group fitted to a flight also fits
    part of its slow sensor noise, and a re-fit on its residual would then under-state that
    noise and let further slow groups pass. A group that cannot absorb it (the eddy lag, the
    sensor lag: T̈-like columns) leaves an honest re-fit, and the old coloured part was that
    effect's own field, fitted as noise before it entered; keeping it would leave the slow
    sensor noise unmodelled and the tests that follow naive.
    """
    keep = (old.fogm_std_nt > new.fogm_std_nt) & (share >= ABSORBABLE_SHARE)
    noise = NoiseModel(
        white_std_nt=new.white_std_nt,
        fogm_std_nt=np.where(keep, old.fogm_std_nt, new.fogm_std_nt),
        fogm_tau_s=np.where(keep, old.fogm_tau_s, new.fogm_tau_s),
    )
    return noise, keep


def _lag_on_signal(
    prob: _Problem,
    groups: list[Group],
    chosen: list[int],
    base: np.ndarray,
    ctx: EffectContext,
    evidence: dict[int, dict[str, Any]],
) -> None:
    """Rebuild a chosen ``sensor_lag`` group as the modelled fluxgate signal shifted by its lag.

    A lag delays everything the magnetometer sees: ``S(t − τ) − S(t)`` with ``S`` the Earth
    field plus the aircraft field ``T_p + A T + B Ṫ`` plus the additive effects named with it.
    Its part outside the base span is ``τ²/2 T̈ − τ B T̈`` (to first order in the small B); the
    candidate built from the Earth field alone leaves ``−τ B T̈``, which ``eddy_time_constant``
    (columns ``L_τ Ṫ − Ṫ ≈ −τ_e T̈``, free B_e) then fits — a true lag was named as lag plus
    eddy. ``S`` comes from the joint fit with the lag in, and the two are alternated
    :data:`LAG_SIGNAL_ITERATIONS` times (the coupling is of order τ: a few iterations settle
    it). ``eddy_time_constant`` is then tested against the lag's full signature, and only a
    T̈ term the lag cannot explain names it. The fitted form (``signal_gain``) re-simulates:
    the simulator shifts its signal, base aircraft field and additive effects, the same way.
    """
    lag = next((j for j in chosen[1:] if groups[j - 1].effect == "sensor_lag"), None)
    if lag is None:
        return
    g = groups[lag - 1]
    lag_effect = EFFECTS["sensor_lag"]
    assert g.profile is not None and isinstance(lag_effect, SensorLag)
    for _ in range(LAG_SIGNAL_ITERATIONS):
        beta, _ = prob.fit(chosen)
        signal = ctx.t_b.copy()
        offset = 0
        for j in chosen:
            cols = base if j == 0 else groups[j - 1].columns
            p = cols.shape[2]
            if j != lag:
                signal += np.einsum("kip,p->ki", cols, beta[offset : offset + p])
            offset += p
        g = lag_effect.group(dataclasses.replace(ctx, signal=signal), g.profile)
        groups[lag - 1] = g
        prob.replace(lag, g.columns)
    if lag in evidence:
        evidence[lag]["lag_model"] = "modelled signal shifted (S(t − τ) − S(t))"


def _refine(
    prob: _Problem,
    groups: list[Group],
    fractions: list[float],
    chosen: list[int],
    best: int,
    stats: dict[str, float],
) -> tuple[int, dict[str, float]]:
    """Refine a profiled group's parameter between its grid neighbours (bounded Brent search on
    the explained sum of squares, in log scale); the refined group joins the problem."""
    from scipy.optimize import minimize_scalar

    g = groups[best - 1]
    assert g.rebuild is not None and g.profile is not None
    grid = sorted(x.profile for x in groups if x.family == g.family and x.profile is not None)
    k = grid.index(g.profile)
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    if lo == hi:
        return best, stats
    cache: dict[float, tuple[Group, dict[str, float] | None]] = {}

    def neg_drss(z: float) -> float:
        cand = g.rebuild(float(np.exp(z)))  # type: ignore[misc]
        t = prob.test_columns(chosen, cand.columns)
        cache[z] = (cand, t)
        return -t["drss"] if t else 0.0

    res = minimize_scalar(
        neg_drss, bounds=(np.log(lo), np.log(hi)), method="bounded", options={"xatol": 0.005}
    )
    cand, t = cache.get(res.x, (None, None))
    if cand is None or t is None or t["drss"] <= prob.test(chosen, best)["drss"]:  # type: ignore[index]
        return best, stats
    groups.append(cand)
    fractions.append(fractions[best - 1])
    idx = prob.add(cand.columns)
    assert idx == len(groups)
    return idx, _statistics(t, 1)


def _backward(
    prob: _Problem, groups: list[Group], chosen: list[int], alpha: float
) -> tuple[list[int], list[int]]:
    """Drop named groups without evidence (:func:`_significant`, Holm over the k named) given
    all the others, the lowest ΔBIC first, until every one left has it."""
    retracted: list[int] = []
    while len(chosen) > 1:
        k = len(chosen) - 1
        tests = {}
        for j in chosen[1:]:
            t = prob.test([c for c in chosen if c != j], j)
            tests[j] = None if t is None else _statistics(t, int(groups[j - 1].profile is not None))
        weak = [j for j, t in tests.items() if t is None or not _significant(t, alpha / k)]
        if not weak:
            break
        worst = min(weak, key=lambda j: -math.inf if tests[j] is None else tests[j]["delta_bic"])  # type: ignore[index]
        chosen = [c for c in chosen if c != worst]
        retracted.append(worst)
    return chosen, retracted


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else float("nan")


def _gap(
    data: _Data, before: np.ndarray, after: np.ndarray, white: float
) -> tuple[dict[str, Any], np.ndarray, np.ndarray]:
    """Held-out gap: RMS of measured − simulated above the white-noise floor (the sensor's white
    noise, estimated by the noise model, is no model gap); the raw RMS is reported too."""
    r0 = np.where(data.usable[:, None], data.y - before, 0.0)
    r1 = np.where(data.usable[:, None], data.y - after, 0.0)
    h = data.held_out
    raw0, raw1 = _rms(r0[h]), _rms(r1[h])
    before_nt = math.sqrt(max(raw0**2 - white**2, 0.0))
    after_nt = math.sqrt(max(raw1**2 - white**2, 0.0))
    gap = {
        "rms_before_nt": before_nt,
        "rms_after_nt": after_nt,
        "shrink": before_nt / after_nt if after_nt > 0 else float("inf"),
        "evaluated_on": "held_out",
        "held_out_scheme": data.scheme,
        "definition": "sqrt(RMS² − σ_white²) of measured − simulated on the held-out samples",
        "white_noise_floor_nt": white,
        "raw_rms_before_nt": raw0,
        "raw_rms_after_nt": raw1,
    }
    return (
        gap,
        np.where(data.usable[:, None], r0, np.nan),
        np.where(data.usable[:, None], r1, np.nan),
    )


def _diagnostics(
    data: _Data,
    span: BaseSpan,
    res: np.ndarray,
    noise0: NoiseModel | None,
    noise1: NoiseModel | None,
    lb0: tuple[float, float],
    lb1: tuple[float, float],
) -> dict[str, Any]:
    """Where the base model and the measurement disagree: time, frequency, heading, channels."""
    from scipy.signal import welch

    tt, ok = data.ctx.tt, data.usable
    r = np.where(ok[:, None], res, 0.0)
    block = np.floor((tt - tt[0]) / BLOCK_S).astype(int)
    seg = []
    for b in np.unique(block[ok]):
        k = ok & (block == b)
        seg.append((float(tt[k][0]), float(tt[k][-1]), _rms(r[k])))
    med = float(np.median([s[2] for s in seg]))
    worst = sorted(seg, key=lambda s: -s[2])[:5]
    f, psd = welch(r, fs=1.0 / data.dt, nperseg=min(2048, r.shape[0]), axis=0)
    peaks = []
    total = psd.sum(axis=1)
    from scipy.ndimage import median_filter

    ref = median_filter(total, size=31, mode="nearest")
    for k in np.flatnonzero((total > 10 * ref) & (f > 0)):
        left_ok = k == 0 or total[k] >= total[k - 1]
        if left_ok and (k + 1 >= total.size or total[k] >= total[k + 1]):
            peaks.append({"frequency_hz": float(f[k]), "excess": float(total[k] / ref[k])})
    yaw = np.degrees(np.arctan2(data.ctx.c_nb[:, 1, 0], data.ctx.c_nb[:, 0, 0])) % 360.0
    bins = np.floor(yaw / 30.0).astype(int)
    heading = {}
    for b in range(12):
        k = ok & (bins == b)
        if k.sum() > 10:
            heading[f"{30 * b}-{30 * b + 30}"] = np.round(r[k].mean(axis=0), 4).tolist()
    means = np.array(list(heading.values())) if heading else np.zeros((1, 3))
    corr = {}
    rows = data.calibration
    for nm, ch in data.ctx.aux.items():
        x = np.zeros((data.ctx.n, 3, 3))
        for i in range(3):
            x[:, i, i] = ch
        xp = span.perp(x).reshape(3, -1, 3)
        rr = r[rows]
        cs = []
        for i in range(3):
            u, v = xp[i, :, i], rr[:, i]
            den = float(np.linalg.norm(u) * np.linalg.norm(v))
            cs.append(float(u @ v / den) if den > 0 else 0.0)
        corr[nm] = {
            "partial_correlation": np.round(cs, 4).tolist(),
            "max_abs": float(np.max(np.abs(cs))),
        }
    return {
        "segments": {
            "block_s": BLOCK_S,
            "median_rms_nt": med,
            "worst": [{"t0_s": a, "t1_s": b, "rms_nt": c} for a, b, c in worst],
            "flagged": [{"t0_s": a, "t1_s": b, "rms_nt": c} for a, b, c in seg if c > 2 * med],
        },
        "spectrum": {"peaks": peaks[:8], "rms_nt": _rms(r[ok])},
        "heading_bins_mean_nt": heading,
        "heading_range_nt": np.round(means.max(axis=0) - means.min(axis=0), 4).tolist(),
        "aux_partial_correlation": corr,
        "whiteness": {
            "ljung_box_lags": 20,
            "before": {"statistic": lb0[0], "p_value": lb0[1]},
            "after": {"statistic": lb1[0], "p_value": lb1[1]},
        },
        "noise_model_before": noise0.to_dict() if noise0 else None,
        "noise_model_after": noise1.to_dict() if noise1 else None,
    }


def _physical(g: Group, b: np.ndarray, se: np.ndarray) -> dict[str, Any]:
    """Parameters in physical units with 95 % intervals, where the effect has a natural one."""
    ci = lambda v, s: [float(v - 1.96 * s), float(v + 1.96 * s)]  # noqa: E731
    if g.effect == "sensor_lag":
        return {
            "lag_s": g.profile,
            "gain": float(b[0]),
            "ci95": ci(float(b[0]), float(se[0])),
            "shifted": g.labels[0],
        }
    if g.effect in ("onboard_current", "altitude_gradient") or (
        g.effect == "permanent_field_drift" and g.channel
    ):
        unit = {
            "onboard_current": "nT per channel unit",
            "altitude_gradient": "nT/m (NED)",
            "permanent_field_drift": "nT per channel unit",
        }[g.effect]
        return {
            "coefficients": b.tolist(),
            "unit": unit,
            "ci95": [ci(v, s) for v, s in zip(b, se, strict=True)],
            "magnitude": float(np.linalg.norm(b)),
        }
    return {"coefficients": dict(zip(g.labels, b.tolist(), strict=True))}


def _base_dict(state: np.ndarray) -> dict[str, list[float]]:
    return {
        "permanent_nt": state[:3].tolist(),
        "induced": state[3:12].tolist(),
        "eddy_s": state[12:].tolist(),
    }


def _round(d: dict[str, float]) -> dict[str, float]:
    return {k: (float(f"{v:.6g}") if isinstance(v, float) else v) for k, v in d.items()}


def _model_config(
    flight: Flight, flux: str, state: np.ndarray, noise: NoiseModel | None, missing: list[dict]
) -> Any:
    """The augmented model as a simulator configuration (replay the flight to re-simulate it)."""
    from aeromag_env.configs import from_json
    from aeromag_env.simulation.config import (
        EarthConfig,
        EffectConfig,
        InterferenceConfig,
        ScalarConfig,
        SensorNoiseConfig,
        SimulationConfig,
        TrajectoryConfig,
    )

    traj = TrajectoryConfig()
    if "config" in flight.attrs:
        with contextlib.suppress(AeromagError):
            traj = from_json(SimulationConfig, flight.attrs["config"]).trajectory
    assert noise is not None
    return SimulationConfig(
        preset="discovered",
        fluxgate=flux,
        trajectory=traj,
        earth=EarthConfig(daily_amplitude_nt=0.0, external_fogm_std_nt=0.0),
        interference=InterferenceConfig(
            permanent_std_nt=0.0,
            induced_std=0.0,
            eddy_std_s=0.0,
            permanent_nt=tuple(state[:3]),
            induced=tuple(state[3:12]),
            eddy_s=tuple(state[12:]),
        ),
        fluxgate_noise=SensorNoiseConfig(
            white_std_nt=float(np.median(noise.white_std_nt)),
            fogm_std_nt=float(np.median(noise.fogm_std_nt)),
            fogm_tau_s=float(np.median(noise.fogm_tau_s)),
        ),
        scalar=ScalarConfig(enabled=False),
        effects=tuple(
            EffectConfig(name=e["name"], channel=e["channel"], parameters=e["parameters"])
            for e in missing
        ),
    )
