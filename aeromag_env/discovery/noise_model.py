"""Noise model of the residual: per axis, white noise plus a first-order Gauss–Markov process
(the fluxgate's coloured noise), fitted by maximum likelihood.

Decides how the residual's noise is modelled and whitened (Kalman innovations, so tests are
not fooled by coloured noise), whether the whitened residual is white (Ljung–Box), and how the
noise model may change after an effect enters the model (:func:`ratchet`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aeromag_env.discovery.segments import Segments
from aeromag_env.numba_cache import njit
from aeromag_env.threads import map_threads

#: An entered group that could absorb less than this share of the coloured noise's variance
#: (per axis) cannot be why the re-fitted coloured part shrank: the re-fit stands.
ABSORBABLE_SHARE = 0.05


@dataclass(frozen=True)
class NoiseModel:
    """White noise plus a first-order Gauss–Markov process, per axis (arrays of 3).

    Attributes
    ----------
    white_std_nt : numpy.ndarray
        White-noise standard deviation per axis [nT].
    fogm_std_nt : numpy.ndarray
        Standard deviation of the first-order Gauss–Markov process per axis [nT].
    fogm_tau_s : numpy.ndarray
        Correlation time of the first-order Gauss–Markov process per axis [s].
    """

    white_std_nt: np.ndarray
    fogm_std_nt: np.ndarray
    fogm_tau_s: np.ndarray

    def to_dict(self) -> dict[str, list[float]]:
        """The model as JSON-ready lists of 3 floats, one per field."""
        return {
            k: [float(v) for v in getattr(self, k)]
            for k in ("white_std_nt", "fogm_std_nt", "fogm_tau_s")
        }


#: The FOGM state estimate is set to 0 below this magnitude. Where a column ends (a spline
#: outside its support) the state decays geometrically into subnormal numbers, and every later
#: product with them ran at a hundredth of the speed: the Gram matrix of the whitened
#: external-field splines took 140 ms instead of 25. Every quantity here is far above 1e-150.
FLUSH = 1e-150


@njit(cache=True, nogil=True)
def _innovations(
    x: np.ndarray,
    rows: np.ndarray,
    axis: int,
    gap: np.ndarray,
    tau: float,
    fogm_var: float,
    white_var: float,
    out: np.ndarray,
) -> None:
    """Normalised Kalman innovations of the columns ``x[rows, axis, :]`` (m, c) of ``x`` (N, A, c)
    into ``out`` (m, c), under ``y = f + w``: ``f`` a FOGM of variance ``fogm_var`` and
    correlation time ``tau``, ``w`` white of variance ``white_var``.

    ``gap[k]`` is the time since the previous row [s] (``inf``: independent restart), so rows
    left out (held-out blocks) or lost (time gaps) are bridged exactly: the FOGM state is
    propagated across them. The gains do not depend on the data, so one pass whitens every
    column, and each column's innovations depend on that column alone (whitened alone or among
    others, a column gets the same bits). Reading the rows through ``rows`` lets a group's
    columns on every sample, (N, 3, c), be whitened on the calibration rows without a copy. A
    state estimate below :data:`FLUSH` is 0 (no subnormal numbers).
    """
    m, c = out.shape
    f = np.zeros(c)
    p = fogm_var
    last_gap, a = math.nan, 1.0
    g, rs, settled = 0.0, 1.0, False
    for k in range(m):
        if gap[k] != last_gap:  # the sampling interval rarely changes: exp once per change
            last_gap = gap[k]
            a = math.exp(-last_gap / tau)
            settled = False
        if not settled:
            # the variance recursion (a serial chain through a division) reaches its exact
            # floating-point fixed point after enough rows at one sampling interval; from there
            # on p, s, g and rs are the same every row, so skipping it changes no bit
            p_in = p
            p = a * a * p + fogm_var * (1.0 - a * a)
            s = p + white_var
            g = p / s
            rs = 1.0 / math.sqrt(s)
            p = (1.0 - g) * p
            settled = p == p_in
        row = rows[k]
        for j in range(c):
            fj = f[j] * a
            v = x[row, axis, j] - fj
            out[k, j] = v * rs
            fj = fj + g * v
            f[j] = fj if abs(fj) >= FLUSH else 0.0


@njit(cache=True, nogil=True)
def _log_likelihood(
    x: np.ndarray, gap: np.ndarray, tau: float, fogm_var: float, white_var: float
) -> float:
    """Gaussian log-likelihood of the series ``x`` (m,) under the noise model of
    :func:`_innovations` (the same recursion, one column, nothing stored: the noise model's
    maximum-likelihood search calls it a thousand times per fit)."""
    f = 0.0
    p = fogm_var
    ll = 0.0
    last_gap, a, last_s, log_s = math.nan, 1.0, math.nan, 0.0
    g, rs, settled = 0.0, 1.0, False
    for k in range(x.size):
        if gap[k] != last_gap:
            last_gap = gap[k]
            a = math.exp(-last_gap / tau)
            settled = False
        if not settled:
            p_in = p
            p = a * a * p + fogm_var * (1.0 - a * a)
            s = p + white_var
            if s != last_s:  # log once per change of s
                last_s = s
                log_s = math.log(2.0 * math.pi * s)
            g = p / s
            rs = 1.0 / math.sqrt(s)
            p = (1.0 - g) * p
            settled = p == p_in
        f *= a
        v = x[k] - f
        v0 = v * rs
        f = f + g * v
        f = f if abs(f) >= FLUSH else 0.0
        ll -= 0.5 * (log_s + v0 * v0)
    return ll


@njit(cache=True)
def fogm_quadratic(q: np.ndarray, gap: np.ndarray, tau: float) -> np.ndarray:
    """``q_jᵀ K q_j`` for each column of ``q`` (m, c), with ``K_kl = exp(−|t_k − t_l| / τ)`` the
    correlation of a unit FOGM over rows ``gap`` apart (as in :func:`_innovations`).

    Parameters
    ----------
    q : numpy.ndarray
        Columns (m, c).
    gap : numpy.ndarray
        Time since the previous row (m,) [s]; ``inf`` for an independent restart.
    tau : float
        Correlation time of the FOGM [s].

    Returns
    -------
    numpy.ndarray
        The quadratic form per column (c,).

    Notes
    -----
    One forward pass: ``qᵀ K q = 2 Σ_k q_k F_k − Σ_k q_k²`` with ``F_k = q_k + a_k F_{k−1}``,
    ``a_k = exp(−gap[k] / τ)`` (``F_k = Σ_{l≤k} K_kl q_l``).
    """
    m, c = q.shape
    a = np.exp(-gap / tau)  # once, not once per column
    out = np.zeros(c)
    f = np.zeros(c)
    # row by row, the columns side by side: each column's operations in the same order as one
    # column at a time (the same bits), the recursions of the columns in one vector
    for k in range(m):
        for j in range(c):
            f[j] = q[k, j] + a[k] * f[j]
            out[j] += (2.0 * f[j] - q[k, j]) * q[k, j]
    return out


def whiten(
    x: np.ndarray,
    gap: np.ndarray,
    white: float,
    fogm: float,
    tau: float,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Whitened copy of ``x`` (m, c) under the white + FOGM noise model (one axis).

    Parameters
    ----------
    x : numpy.ndarray
        Columns to whiten (m, c), rows in time order (copied unless C-contiguous: the kernel
        vectorises over a row's columns only then, 3× faster).
    gap : numpy.ndarray
        Time since the previous row (m,) [s]; ``inf`` for an independent restart.
    white, fogm, tau : float
        White-noise std [nT], FOGM std [nT] and FOGM correlation time [s] of the axis.
    out : numpy.ndarray, optional
        Where to write the result (m, c), e.g. one axis's rows of an axis-stacked array.

    Returns
    -------
    numpy.ndarray
        The normalised Kalman innovations of every column (m, c): ``out`` when given.
    """
    if out is None:
        out = np.empty(x.shape)
    x3 = np.ascontiguousarray(x)[:, None, :]
    _innovations(x3, np.arange(x.shape[0]), 0, gap, tau, fogm * fogm, white * white, out)
    return out


def whiten_rows(
    x: np.ndarray,
    rows: np.ndarray,
    axis: int,
    gap: np.ndarray,
    white: float,
    fogm: float,
    tau: float,
    out: np.ndarray,
) -> np.ndarray:
    """:func:`whiten` of the rows ``rows`` of axis ``axis`` of columns ``x`` (N, 3, c) on every
    sample, into ``out`` (m, c) (e.g. one axis's rows and one group's columns of an axis-stacked
    array): no copy of the rows is made. ``x`` must be C-contiguous."""
    _innovations(x, rows, axis, gap, tau, fogm * fogm, white * white, out)
    return out


#: A whitened sparse column's tail (past its last non-zero input) is cut where it falls below
#: this share of the largest value of its axis's segment: its part of any product with another
#: column is then below 1e-19 of that product, under the last bit of a double (1.1e-16). The
#: dense kernel carries it on to :data:`FLUSH`.
TAIL_TOL = 1e-20


@njit(cache=True, nogil=True)
def _gains(
    gap: np.ndarray, tau: float, fogm_var: float, white_var: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The per-row transition ``a``, Kalman gain ``g`` and innovation scale ``rs`` (each (m,))
    of :func:`_innovations` (the same recursion, so the same bits)."""
    m = gap.size
    a_k, g_k, rs_k = np.empty(m), np.empty(m), np.empty(m)
    p = fogm_var
    last_gap, a = math.nan, 1.0
    g, rs, settled = 0.0, 1.0, False
    for k in range(m):
        if gap[k] != last_gap:
            last_gap = gap[k]
            a = math.exp(-last_gap / tau)
            settled = False
        if not settled:
            p_in = p
            p = a * a * p + fogm_var * (1.0 - a * a)
            s = p + white_var
            g = p / s
            rs = 1.0 / math.sqrt(s)
            p = (1.0 - g) * p
            settled = p == p_in
        a_k[k], g_k[k], rs_k[k] = a, g, rs
    return a_k, g_k, rs_k


@njit(cache=True, nogil=True)
def _whiten_runs(
    start: np.ndarray,
    length: np.ndarray,
    offset: np.ndarray,
    values: np.ndarray,
    m: int,
    gains: np.ndarray,
    out_length: np.ndarray,
    out_offset: np.ndarray,
    out_values: np.ndarray,
) -> None:
    """Whiten columns held as runs (:class:`~aeromag_env.discovery.segments.Segments`, rows 3m)
    axis by axis, into runs that start where the input's do.

    ``gains`` (3, 3, m) holds each axis's ``a``, ``g`` and ``rs`` (:func:`_gains`). A run starts
    with a zero state (the dense kernel's state is exactly 0 before a column's first non-zero
    row) and goes on past the input's run until the innovations fall below :data:`TAIL_TOL` of
    the run's largest, the state is flushed (:data:`FLUSH`) or the axis ends. With
    ``out_values`` empty only the lengths are counted (into ``out_length``).
    """
    count = out_values.size == 0
    p = start.shape[0]
    for j in range(p):
        for i in range(3):
            n_in = length[j, i]
            if n_in == 0:
                if count:
                    out_length[j, i] = 0
                continue
            a, g, rs = gains[i, 0], gains[i, 1], gains[i, 2]
            k0 = start[j, i] - i * m
            o_in = offset[j, i]
            o_out = out_offset[j, i]
            f, biggest, n = 0.0, 0.0, 0
            for k in range(k0, m):
                r = k - k0
                inside = r < n_in
                x = values[o_in + r] if inside else 0.0
                fj = f * a[k]
                v = x - fj
                w = v * rs[k]
                fj = fj + g[k] * v
                f = fj if abs(fj) >= FLUSH else 0.0
                biggest = max(biggest, abs(w))
                if not inside and abs(w) < TAIL_TOL * biggest:
                    break  # the tail is below the last bit of any product with it
                if not count:
                    out_values[o_out + n] = w
                n += 1
                if not inside and f == 0.0:
                    break  # flushed: the dense kernel's innovations are exactly 0 from here
            if count:
                out_length[j, i] = n


def whiten_segments(x: Segments, gap: np.ndarray, noise: NoiseModel) -> Segments:
    """:func:`whiten` of axis-stacked columns held as runs (:class:`~aeromag_env.discovery.
    segments.Segments`, rows 3m) under ``noise``: runs from each input run's first row to where
    its tail falls below :data:`TAIL_TOL` (the values kept are the dense kernel's, bit for bit)."""
    m = gap.size
    gains = np.empty((3, 3, m))
    for i in range(3):
        gains[i] = _gains(
            gap, noise.fogm_tau_s[i], noise.fogm_std_nt[i] ** 2, noise.white_std_nt[i] ** 2
        )
    args = (x.start, x.length, x.offset, x.values, m, gains)
    length = np.zeros_like(x.length)
    _whiten_runs(*args, length, np.zeros_like(x.length), np.empty(0))
    offset = (np.cumsum(length.ravel()) - length.ravel()).reshape(length.shape)
    values = np.empty(int(length.sum()))
    _whiten_runs(*args, length, offset, values)
    return Segments(x.rows, x.start, length, offset, values)


def log_likelihood(r: np.ndarray, gap: np.ndarray, noise: NoiseModel) -> float:
    """Gaussian log-likelihood of the residual ``r`` (m, 3) under ``noise`` (axes independent)."""
    return sum(
        _log_likelihood(
            np.ascontiguousarray(r[:, i]),
            gap,
            noise.fogm_tau_s[i],
            noise.fogm_std_nt[i] ** 2,
            noise.white_std_nt[i] ** 2,
        )
        for i in range(3)
    )


def fit_noise(r: np.ndarray, gap: np.ndarray, start: NoiseModel | None = None) -> NoiseModel:
    """Maximum-likelihood white + FOGM model of each column of the residual ``r`` (m, 3).

    Parameters
    ----------
    r : numpy.ndarray
        Residual (m, 3), rows in time order.
    gap : numpy.ndarray
        Time since the previous row (m,) [s]; ``inf`` for an independent restart.
    start : NoiseModel, optional
        A model to start from (a re-fit after a small change of the residual): one search from
        it instead of the two default starts.

    Returns
    -------
    NoiseModel
        The fitted model, one value per axis.
    """
    starts = [
        None
        if start is None
        else (start.white_std_nt[i], start.fogm_std_nt[i], start.fogm_tau_s[i])
        for i in range(3)
    ]
    # the axes are independent and the kernel releases the GIL: one thread each (bit-identical)
    fits = map_threads(
        lambda i: _fit_one(np.ascontiguousarray(r[:, i : i + 1]), gap, starts[i]), range(3)
    )
    white, fogm, tau = (np.array(v) for v in zip(*fits, strict=True))
    return NoiseModel(white, fogm, tau)


def _fit_one(
    col: np.ndarray, gap: np.ndarray, start: tuple[float, float, float] | None = None
) -> tuple[float, float, float]:
    """Maximum-likelihood (white std, FOGM std, FOGM τ) of one residual column (m, 1); Nelder–Mead
    in log parameters from ``start``, or else from a 60-s and a 600-s start, the better kept."""
    from scipy.optimize import minimize

    series = col[:, 0]
    sd = float(np.std(col)) or 1.0
    w0 = max(float(np.std(np.diff(col[:, 0]))) / math.sqrt(2.0), 1e-3 * sd)  # from differences
    f0 = max(math.sqrt(max(sd * sd - w0 * w0, 0.0)), 1e-2 * sd)

    def nll(z: np.ndarray) -> float:
        with np.errstate(over="ignore"):  # τ → ∞ is a random walk's limit, not an error
            w, f, t = np.exp(z)
        if t == 0.0 or w * w + f * f == 0.0:  # underflow: on a white residual the search may
            return math.inf  # drive τ to 0 (the FOGM becomes white noise too)
        return -_log_likelihood(series, gap, t, f * f, w * w)

    opts = {"xatol": 1e-2, "fatol": 1e-2, "maxiter": 200}
    points = [(w0, f0, 60.0), (w0, f0, 600.0)] if start is None else [start]
    runs = [
        minimize(nll, np.log(np.maximum(x0, 1e-6)), method="Nelder-Mead", options=opts)
        for x0 in points
    ]
    w, f, t = np.exp(min(runs, key=lambda res: res.fun).x)
    return float(w), float(f), float(min(t, 1e6))


def ljung_box(x: np.ndarray, lags: int = 20) -> tuple[float, float]:
    """Ljung–Box statistic and p-value of a series (mean removed).

    Parameters
    ----------
    x : numpy.ndarray
        The series.
    lags : int
        Number of autocorrelation lags summed.

    Returns
    -------
    tuple of float
        The statistic ``Q`` and its χ² p-value with ``lags`` degrees of freedom.
    """
    from scipy.stats import chi2

    x = np.asarray(x, float) - np.mean(x)
    n = x.size
    den = float(np.dot(x, x))
    rho = np.array([np.dot(x[:-k], x[k:]) / den for k in range(1, lags + 1)])
    q = float(n * (n + 2) * np.sum(rho**2 / (n - np.arange(1, lags + 1))))
    return q, float(chi2.sf(q, lags))


def ratchet(old: NoiseModel, new: NoiseModel, share: np.ndarray) -> tuple[NoiseModel, np.ndarray]:
    """Noise model after an effect entered, and the axes (3,) whose coloured part was kept.

    Parameters
    ----------
    old : NoiseModel
        The noise model before the effect entered.
    new : NoiseModel
        The noise model re-fitted on the residual with the effect in.
    share : numpy.ndarray
        Per axis (3,), the share of the coloured noise's variance the entered group could
        absorb (:meth:`~aeromag_env.discovery.whitened_problem.WhitenedProblem.absorbable_share`).

    Returns
    -------
    tuple of (NoiseModel, numpy.ndarray)
        The noise model to use, and per axis whether the old coloured part was kept.

    Notes
    -----
    The re-fit's white part always; its coloured part too, except that it does not shrink (per axis,
    the larger FOGM of the two, with its correlation time) where the entered group could absorb at
    least :data:`ABSORBABLE_SHARE` of the coloured noise: a slow, flexible group fitted to a flight
    also fits part of its slow sensor noise, and a re-fit on its residual would then under-state
    that noise and let further slow groups pass. A group that cannot absorb it (the eddy lag, the
    sensor lag: T̈-like columns) leaves an honest re-fit, and the old coloured part was that
    effect's own field, fitted as noise before it entered; keeping it would leave the slow sensor
    noise unmodelled and the tests that follow naive.
    """
    keep = (old.fogm_std_nt > new.fogm_std_nt) & (share >= ABSORBABLE_SHARE)
    noise = NoiseModel(
        white_std_nt=new.white_std_nt,
        fogm_std_nt=np.where(keep, old.fogm_std_nt, new.fogm_std_nt),
        fogm_tau_s=np.where(keep, old.fogm_tau_s, new.fogm_tau_s),
    )
    return noise, keep
