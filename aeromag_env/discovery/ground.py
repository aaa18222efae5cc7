"""Ground separation: the band where aircraft effects live, apart from the magnetic ground.

Decides what of a survey line's residual is crustal geology and is therefore left out of every
fit, test and gap. The ground's field is fixed in the navigation frame and, seen from a
clearance ``h`` above it, holds almost no wavelengths shorter than about ``2 h`` (upward
continuation damps wavenumber ``k`` by ``exp(−k h)``). So on each run of consecutive samples of
one part (calibration or held out), the ground is modelled as three navigation-frame cubic
B-splines in time, rotated into body axes by the attitude (``C_bnᵀ e_j N_m(t)``, the form of
``external_field_variation``), with knots every :data:`KNOTS_PER_CLEARANCE` ``× h`` metres of
track (``h`` the run's 5th-percentile clearance), or closer (:data:`KNOT_FACTORS`, at least
:data:`MIN_KNOT_SPACING_S` apart) where AIC says strong ground leaves enough between them.

The measured-minus-model series and every regressor are projected off that span, run by run
(Frisch–Waugh–Lovell): what the workflow then fits, tests and scores is the part of the data
the ground cannot explain. A calibration box flown high keeps its manoeuvres (knots tens of
seconds apart); on low, straight lines little but fast effects survive. A candidate whose
variance the ground span takes almost entirely cannot be told from geology on this flight,
and the report says so (:data:`SEPARABLE_FRACTION`).

Clearance is, sample by sample, the radar altimeter (``radar``) where it is finite, else the
altitude above the terrain model (``alt − dem``), else the altitude itself (the ground taken at
sea level, which is what the simulator's geology assumes); the report says how much came from
each. A radar that holds its maximum out of range, rather than reporting NaN, is not detected.
On 50 nT of simulated ground at 400 m the splines leave under 2 % of its RMS
(``tests/discovery/test_discover_ground.py``); over 0–200 nT no plain flight named anything
(``python -m experiments.discovery_ground``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from aeromag_env.discovery.base_model import orthonormal, stack
from aeromag_env.flight.data import Flight
from aeromag_env.flight.quality import ground_speed
from aeromag_env.simulation.effects import Group
from aeromag_env.simulation.effects_base import spline_basis, spline_knots

#: What discovery does with the magnetic ground: ``ignore`` it (a calibration box flown high),
#: or ``separate`` it (this module; survey lines).
GROUND_MODES = ("ignore", "separate")
#: Knot spacing along the track per metre of clearance: the ground's shortest wavelengths at
#: clearance h are about 2 h, and cubic splines follow wavelengths down to about 3 knots. The
#: coarsest spacing; :data:`KNOT_FACTORS` are those tried, by AIC, for strong ground.
KNOTS_PER_CLEARANCE = 0.5
KNOT_FACTORS = (KNOTS_PER_CLEARANCE, 0.35, 0.25, 0.18, 0.125)
#: A run with fewer samples is left out (its ground would take most of it).
MIN_RUN_SAMPLES = 50
#: The closest knots in time [s] (very low or slow flight).
MIN_KNOT_SPACING_S = 1.0
#: The lowest clearance used [m]: below it (a bad radar sample) the knots would be absurdly dense.
MIN_CLEARANCE_M = 30.0
#: A candidate with less of its variance than this outside the ground span cannot be told from
#: geology on this flight; the report lists it.
SEPARABLE_FRACTION = 0.1
#: A field along the Earth field, fixed in the navigation frame, is an isotropic induced term
#: ``a T`` to the base model: the ground cannot be told from it (the Earth field changes too
#: little along a run for the splines to miss it). :func:`base_off_ground` drops that direction
#: from the base, and :func:`as_fitted` leaves that part of ``A`` at 0.
ISOTROPIC_NOTE = (
    "the isotropic part of A (a·I: a field along the Earth field) cannot be told from the "
    "ground and is left at 0 in base_model and model_config"
)


@dataclass
class Run:
    """Usable samples ``idx`` of one run and the orthonormal basis ``q`` (3m, r) of the ground
    there, on axis-stacked rows; ``spacing_s`` the knot spacing [s], ``clearance_m`` the run's
    5th-percentile clearance [m] and ``knots_per_clearance`` the knots' spacing along the track
    in clearances."""

    idx: np.ndarray
    q: np.ndarray
    spacing_s: float
    clearance_m: float
    knots_per_clearance: float


@dataclass
class GroundReference:
    """The ground's span run by run, and the projection off it.

    Attributes
    ----------
    runs : list of Run
        One per run of consecutive samples of one part, between time gaps.
    clearance_source : str
        Where the clearance came from (``radar``, ``alt − dem`` or ``alt``).
    dropped : list of numpy.ndarray
        Samples of runs too short to tell anything from the ground (:data:`MIN_RUN_SAMPLES`):
        the workflow leaves them out.
    """

    runs: list[Run] = field(default_factory=list)
    clearance_source: str = ""
    dropped: list[np.ndarray] = field(default_factory=list)

    def remove(self, x: np.ndarray) -> np.ndarray:
        """``x`` (n, 3) or (n, 3, p) with each run's part in the ground span removed (a copy;
        samples in no run, never used, are left as they are)."""
        out = np.array(x, dtype=float, copy=True)
        cols = out if out.ndim == 3 else out[:, :, None]
        for run in self.runs:
            m = run.idx.size
            xs = stack(cols[run.idx])
            xs -= run.q @ (run.q.T @ xs)
            cols[run.idx] = xs.reshape(3, m, -1).transpose(1, 0, 2)
        return out

    def group(self, g: Group) -> Group:
        """Group ``g`` with its columns off the ground, and so every group it rebuilds."""
        rebuild = g.rebuild
        wrapped = None if rebuild is None else (lambda v: self.group(rebuild(v)))
        return replace(g, columns=self.remove(g.columns), rebuild=wrapped)

    def separate(self, g: Group, rows: np.ndarray) -> tuple[Group, float]:
        """:meth:`group` of ``g``, and the share of its centred variance on ``rows`` that the
        ground span leaves, mean over its columns (1 for a group that does not vary)."""
        off = self.group(g)
        raw = g.columns[rows] - g.columns[rows].mean(axis=0, keepdims=True)
        kept = off.columns[rows]
        total = np.einsum("kip,kip->p", raw, raw)
        ok = total > 1e-18 * max(float(total.max(initial=0.0)), 1e-300)
        if not ok.any():
            return off, 1.0
        left = np.einsum("kip,kip->p", kept, kept)
        return off, float(np.mean(np.minimum(left[ok] / total[ok], 1.0)))

    def record(self) -> dict[str, Any]:
        """What the report says of the ground reference."""
        spacing = [r.spacing_s for r in self.runs]
        return {
            "mode": "separate",
            "model": "navigation-frame cubic B-splines per run, rotated by the attitude; every "
            "series and regressor projected off them",
            "base_model": ISOTROPIC_NOTE,
            "clearance_source": self.clearance_source,
            "runs": len(self.runs),
            "columns": int(sum(r.q.shape[1] for r in self.runs)),
            "knot_spacing_s": [min(spacing), max(spacing)] if spacing else [],
            "knots_per_clearance": sorted({r.knots_per_clearance for r in self.runs}),
            "samples_dropped": int(sum(d.size for d in self.dropped)),
            "clearance_m": [
                min(r.clearance_m for r in self.runs),
                max(r.clearance_m for r in self.runs),
            ]
            if self.runs
            else [],
        }


def ground_reference(
    flight: Flight,
    c_nb: np.ndarray,
    y: np.ndarray,
    base: np.ndarray,
    usable: np.ndarray,
    calibration: np.ndarray,
) -> GroundReference:
    """The ground's span on each run of usable samples of one part (calibration or held out).

    Parameters
    ----------
    flight : Flight
        The flight: time, position, altitude and, if present, ``radar`` or ``dem``.
    c_nb : numpy.ndarray
        Attitude DCMs (n, 3, 3), body to navigation.
    y : numpy.ndarray
        Measured minus model Earth field (n, 3) [nT], to choose the knots by.
    base : numpy.ndarray
        The base regressors (n, 3, 21).
    usable, calibration : numpy.ndarray
        Boolean masks (n,) of the usable samples and of the calibration part.

    Returns
    -------
    GroundReference
        One :class:`Run` per run; runs are split where the part changes and at time gaps.
        Runs under :data:`MIN_RUN_SAMPLES` are listed in ``dropped``.

    Notes
    -----
    Knots per run by AIC (:func:`_knot_factor`) on the residual of the base model fitted on the
    calibration runs off the coarsest ground: strong ground leaves more of itself between
    coarse knots than closer ones cost (fixed at half the clearance, 200 nT of simulated
    ground named effects on 6 of 20 plain flights).
    """
    tt = flight.tt
    clearance, source = _clearance(flight)
    speed = _speed(flight)
    ref = GroundReference(clearance_source=source)
    runs = []
    for idx in _runs(tt, usable, calibration):
        if idx.size < MIN_RUN_SAMPLES:
            ref.dropped.append(idx)
            continue
        # a low percentile, not the minimum: one bad radar sample must not set the knots
        h = float(np.nanpercentile(clearance[idx], 5)) if np.isfinite(clearance[idx]).any() else 0
        h = max(h, MIN_CLEARANCE_M)
        v = float(np.nanmedian(speed[idx]))
        runs.append((idx, h, v))
    coarse = [_span(tt, c_nb, idx, _spacing(tt, idx, KNOT_FACTORS[0], h, v)) for idx, h, v in runs]
    resid = y - np.einsum("kip,p->ki", base, _base_fit(runs, coarse, y, base, calibration))
    for run, first in zip(runs, coarse, strict=True):
        idx, h, v = run
        factor = _knot_factor(tt, c_nb, run, stack(resid[idx][:, :, None])[:, 0], first)
        if factor != KNOT_FACTORS[0]:
            first = _span(tt, c_nb, idx, _spacing(tt, idx, factor, h, v))
        ref.runs.append(Run(idx, first[0], first[1], h, factor))
    return ref


def _knot_factor(
    tt: np.ndarray,
    c_nb: np.ndarray,
    run: tuple[np.ndarray, float, float],
    r: np.ndarray,
    coarse: tuple[np.ndarray, float],
) -> float:
    """The entry of :data:`KNOT_FACTORS` with the least AIC for residual ``r`` (3m,) on ``run``
    (its samples, clearance and speed), given its coarsest basis and spacing."""
    idx, h, v = run
    q, spacing = coarse
    best, best_aic = KNOT_FACTORS[0], _aic(r, q.shape[1], float(np.sum((q.T @ r) ** 2)))
    for factor in KNOT_FACTORS[1:]:
        closer = _spacing(tt, idx, factor, h, v)
        if closer >= spacing:  # at the closest knots already
            break
        spacing = closer
        x = _columns(tt, c_nb, idx, spacing)
        if x.shape[1] * 2 > r.size:
            break
        aic = _aic(r, x.shape[1], _explained(x, r))
        if aic < best_aic:
            best, best_aic = factor, aic
    return best


def _runs(tt: np.ndarray, usable: np.ndarray, calibration: np.ndarray) -> list[np.ndarray]:
    """Indices of each run of usable samples of one part, split at time gaps."""
    used = np.flatnonzero(usable)
    step = np.diff(tt)
    segment = np.r_[0, np.cumsum(step > 1.5 * np.median(step))]
    breaks = (np.diff(calibration[used].astype(int)) != 0) | (np.diff(segment[used]) != 0)
    return np.split(used, np.flatnonzero(breaks) + 1)


def _spacing(tt: np.ndarray, idx: np.ndarray, factor: float, h: float, v: float) -> float:
    """Knot spacing [s]: ``factor × h`` metres of track at speed ``v``, within the run."""
    spacing = factor * h / v if v > 0 else np.inf
    return min(max(spacing, MIN_KNOT_SPACING_S), float(tt[idx[-1]] - tt[idx[0]]))


def _columns(tt: np.ndarray, c_nb: np.ndarray, idx: np.ndarray, spacing: float) -> np.ndarray:
    """The ground's columns on run ``idx``, knots ``spacing`` apart, axis-stacked (3m, 3K):
    ``C_bnᵀ e_j N_k(t)`` as :func:`~aeromag_env.simulation.effects_base.nav_columns` builds
    them (body axis, spline, NED axis)."""
    span = (float(tt[idx[0]]), float(tt[idx[-1]]))
    basis = spline_basis(tt[idx], spline_knots(span, spacing))
    return stack(np.einsum("km,kji->kimj", basis, c_nb[idx]).reshape(idx.size, 3, -1))


def _span(
    tt: np.ndarray, c_nb: np.ndarray, idx: np.ndarray, spacing: float
) -> tuple[np.ndarray, float]:
    """Orthonormal basis (3m, r) of the ground on run ``idx`` with knots ``spacing`` apart, and
    the spacing."""
    return orthonormal(_columns(tt, c_nb, idx, spacing)), spacing


def _explained(x: np.ndarray, r: np.ndarray) -> float:
    """Sum of squares of ``r`` in the span of the full-rank columns ``x``, from their Gram
    matrix (no basis needed to compare knot spacings)."""
    from scipy.linalg import cho_factor, cho_solve

    xr = x.T @ r
    return float(xr @ cho_solve(cho_factor(x.T @ x), xr))


def _base_fit(
    runs: list[tuple[np.ndarray, float, float]],
    spans: list[tuple[np.ndarray, float]],
    y: np.ndarray,
    base: np.ndarray,
    calibration: np.ndarray,
) -> np.ndarray:
    """Ordinary least-squares base coefficients on the calibration runs, off their ground."""
    from scipy.linalg import lstsq

    xs, ys = [], []
    for (idx, _, _), (q, _) in zip(runs, spans, strict=True):
        if calibration[idx[0]]:
            x, t = stack(base[idx]), stack(y[idx][:, :, None])
            xs.append(x - q @ (q.T @ x))
            ys.append(t - q @ (q.T @ t))
    if not xs:
        return np.zeros(base.shape[2])
    beta = lstsq(np.vstack(xs), np.vstack(ys), cond=1e-9, lapack_driver="gelsy")[0]
    return np.asarray(beta)[:, 0]


def _aic(r: np.ndarray, p: int, explained: float) -> float:
    """AIC of residual ``r`` (3m,) taken off ``p`` ground columns that explain ``explained`` of
    its sum of squares: ``N log(RSS / N) + 2 p``."""
    rss = max(float(r @ r) - explained, 1e-300)
    return float(r.size * math.log(rss / r.size) + 2 * p)


def base_off_ground(ref: GroundReference, base: np.ndarray) -> np.ndarray:
    """The base columns (n, 3, 21) off the ground, without the direction the ground holds.

    Off the ground, the three diagonal columns of ``A`` (``T_i`` on axis i) nearly sum to 0
    (:data:`ISOTROPIC_NOTE`), and a fit would give ``a`` from what little is left; the last of
    them is zeroed, so its ``A_zz`` is 0. :func:`as_fitted` then moves the isotropic part out
    of the fitted ``A``.
    """
    out = ref.remove(base)
    out[:, 2, 7 * 2 + 1 + 2] = 0.0
    return out


def as_fitted(beta: np.ndarray, ref: GroundReference | None) -> np.ndarray:
    """Coefficients (base first, axis-major) as the base model reads them: off the ground,
    with the isotropic part of ``A`` removed (a copy), since only ``A``'s traceless part is
    fitted there (:func:`base_off_ground`; predictions off the ground use ``beta`` as fitted)."""
    if ref is None:
        return beta
    out = np.array(beta, dtype=float, copy=True)
    diag = [7 * i + 1 + i for i in range(3)]
    out[diag] -= out[diag].mean()
    return out


def _clearance(flight: Flight) -> tuple[np.ndarray, str]:
    """Height above the ground (n,) [m] and where it came from: per sample the radar altimeter,
    else the altitude above the terrain model, else the altitude (a radar out of range or
    dropped out is NaN there, and the next source fills in)."""
    alt_name = flight.altitude_name() or "alt"
    alt = np.asarray(flight[alt_name], float) if alt_name in flight else np.full(flight.n, np.nan)
    sources = [
        ("radar", np.asarray(flight["radar"], float) if "radar" in flight else None),
        (f"{alt_name} − dem", alt - flight["dem"] if "dem" in flight else None),
        (f"{alt_name} (ground at 0 m)", alt),
    ]
    out, used = np.full(flight.n, np.nan), []
    for name, values in sources:
        if values is None:
            continue
        fill = np.isnan(out) & np.isfinite(values)
        if fill.any():
            out[fill] = values[fill]
            used.append(f"{name} on {fill.mean():.0%} of samples")
    return out, ", ".join(used) or "none (no finite radar, dem or altitude)"


def _speed(flight: Flight) -> np.ndarray:
    """Ground speed (n,) [m/s] of the step after each sample; NaN where unknown."""
    speed = np.r_[ground_speed(flight), np.nan]
    speed[~np.isfinite(speed)] = np.nan
    return speed
