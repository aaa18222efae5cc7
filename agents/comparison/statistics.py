"""The learners' benchmark in numbers: each learner's training seeds on the same test flights of
every scenario, against the anchors of the normalized score.

The data are what ``experiments/compare_learners.py evaluate`` writes (``flights.csv``: one RMSE
per learner, seed, scenario and test flight, the reference policies with an empty seed;
``curves.csv``: the validation points of every run; ``runs.json``); the page
``docs/results/learners.md`` is made from them by ``scripts/results_pages.py``. Here:

* per learner, seed and scenario the mean RMSE over the test flights, the normalized score
  ``(RMSE₀ − RMSE) / (RMSE₀ − RMSE₁)`` on the same flights (0 = ``tuned_constant``,
  1 = ``privileged``, as ``agents.evaluation.statistics.normalized_scores``), the tail (CVaR: the
  mean of the worst 10 % of flights) and whether the seed is worse than the tuned constant beyond
  the paired 95 % t interval over flights;
* rliable's aggregates over seeds × scenarios (IQM, mean, optimality gap, probability of
  improvement, performance profiles) with stratified-bootstrap intervals (Agarwal et al. 2021);
* the bar a shipped general policy has to clear, checked per learner;
* the learning curves on the normalized scale, from the validation flights.

A scenario where ``privileged`` is not better than ``tuned_constant`` beyond the paired interval
has no headroom: it is left out of every score.
"""

from __future__ import annotations

import math
import warnings
from collections import defaultdict
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from aeromag_env.errors import AeromagError
from agents.evaluation.statistics import BOOTSTRAP_RESAMPLES, SCORE_ONE, SCORE_ZERO, ci95
from agents.training.learners import LEARNERS

#: The tail: the worst fraction of the flights whose mean RMSE is the CVaR.
CVAR_FRACTION = 0.1
#: The bar's floor on the interquartile mean of the normalized score over seeds × scenarios.
BAR_IQM = 0.6
#: The scenario on which the bar asks for a mean RMSE at most the tuned constant's.
BAR_SCENARIO = "nonstationary"
#: The learner the probability of improvement is measured against.
BASELINE = "ppo"
#: rliable's aggregate metrics, in the order of :func:`aggregates`' values.
AGGREGATES = ("IQM", "mean", "optimality gap")


# --- test flights ------------------------------------------------------------------------------


@dataclass(frozen=True)
class FlightTable:
    """Every policy's RMSE [nT] on the same test flights.

    Attributes
    ----------
    scenarios : tuple of str
        The scenarios, in the data's order.
    flights : ndarray, shape (scenarios, flights)
        The test flights' seeds.
    references : dict of str to ndarray, shape (scenarios, flights)
        The reference policies' (empty seed in the data) RMSE per flight [nT].
    learners : dict of str to ndarray, shape (seeds, scenarios, flights)
        Each learner's RMSE per training seed and flight [nT], learners in the order of
        ``agents.training.learners.LEARNERS`` (others after them), seeds ascending.
    seeds : dict of str to tuple of int
        Each learner's training seeds, in the order of its array's first axis.
    """

    scenarios: tuple[str, ...]
    flights: np.ndarray
    references: dict[str, np.ndarray]
    learners: dict[str, np.ndarray]
    seeds: dict[str, tuple[int, ...]]


def _order(learner: str) -> tuple[int, str]:
    """Learners in the order of ``LEARNERS``, others after them by name."""
    return (LEARNERS.index(learner) if learner in LEARNERS else len(LEARNERS), learner)


def flight_table(rows: Iterable[Mapping[str, str]]) -> FlightTable:
    """The RMSE arrays of ``flights.csv``'s rows (``learner, seed, scenario, flight, rmse_nt``).

    Every learner and seed must have flown exactly the tuned constant's flights in every
    scenario, and every scenario as many flights; a one-line :class:`AeromagError` otherwise.
    """
    table: dict[tuple[str, str], dict[str, dict[int, float]]] = defaultdict(dict)
    scenarios: list[str] = []
    for row in rows:
        per = table[row["learner"], row["seed"]].setdefault(row["scenario"], {})
        per[int(row["flight"])] = float(row["rmse_nt"])
        if row["scenario"] not in scenarios:
            scenarios.append(row["scenario"])
    for anchor in (SCORE_ZERO, SCORE_ONE):
        if (anchor, "") not in table:
            raise AeromagError(f"the test flights have no {anchor} records (empty seed)")
    zero = table[SCORE_ZERO, ""]
    flights = np.array([sorted(zero.get(s, {})) for s in scenarios], dtype=object)
    if flights.ndim != 2 or flights.shape[1] < 1:
        counts = ", ".join(f"{s} {len(zero.get(s, {}))}" for s in scenarios)
        raise AeromagError(f"the scenarios have different numbers of test flights: {counts}")

    def rmse(key: tuple[str, str]) -> np.ndarray:
        per = table[key]
        for k, s in enumerate(scenarios):
            if sorted(per.get(s, {})) != list(flights[k]):
                who = f"{key[0]} seed {key[1]}" if key[1] else key[0]
                raise AeromagError(f"{who} did not fly the tuned constant's flights of {s}")
        return np.array([[per[s][f] for f in flights[k]] for k, s in enumerate(scenarios)])

    names = sorted({name for name, seed in table if seed}, key=_order)
    seeds = {n: tuple(sorted(int(s) for m, s in table if m == n)) for n in names}
    return FlightTable(
        scenarios=tuple(scenarios),
        flights=flights.astype(int),
        references={name: rmse((name, "")) for name, seed in table if not seed},
        learners={n: np.array([rmse((n, str(s))) for s in seeds[n]]) for n in names},
        seeds=seeds,
    )


# --- statistics --------------------------------------------------------------------------------


def tail_size(flights: int, fraction: float = CVAR_FRACTION) -> int:
    """How many of ``flights`` make the tail: ``floor(fraction × flights)``, at least 1."""
    return max(1, math.floor(fraction * flights + 1e-9))  # 0.1 × 30 is 3.0000000000000004


def cvar(rmse: ArrayLike, fraction: float = CVAR_FRACTION) -> np.ndarray:
    """The mean of the worst ``fraction`` of the flights (:func:`tail_size` of them), along the
    last axis.

    Parameters
    ----------
    rmse : array_like, shape (..., flights)
        RMSE per flight [nT].
    fraction : float
        The tail's share of the flights.

    Returns
    -------
    ndarray, shape (...)
        The tail's mean RMSE [nT].
    """
    x = np.sort(np.asarray(rmse, dtype=float), axis=-1)
    return x[..., -tail_size(x.shape[-1], fraction) :].mean(axis=-1)


def normalized_score(rmse: ArrayLike, zero: ArrayLike, one: ArrayLike) -> np.ndarray:
    """``(zero − rmse) / (zero − one)`` on mean RMSEs [nT] (broadcast): 0 at ``zero``, 1 at
    ``one``."""
    zero = np.asarray(zero, dtype=float)
    return (zero - np.asarray(rmse, dtype=float)) / (zero - np.asarray(one, dtype=float))


def exceeds(x: ArrayLike, y: ArrayLike) -> np.ndarray:
    """Whether ``x`` is above ``y`` beyond the paired 95 % t interval over flights (last axis):
    the interval of the mean of ``x − y`` (``agents.evaluation.statistics.ci95``) lies above 0.
    False with fewer than 2 flights.

    Parameters
    ----------
    x, y : array_like, shape (..., flights)
        RMSE per flight [nT] on the same flights (broadcast).

    Returns
    -------
    ndarray of bool, shape (...)
    """
    diff = np.asarray(x, dtype=float) - np.asarray(y, dtype=float)
    low = np.apply_along_axis(lambda d: ci95(d)[0], -1, diff)
    return np.asarray(low > 0)  # NaN (one flight) compares False


def over_seeds(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean over the first axis (training seeds) and its 95 % t interval (``ci95``; NaN with one
    seed): ``(mean, low, high)``, each of shape ``x.shape[1:]``."""
    x = np.asarray(x, dtype=float)
    flat = x.reshape(x.shape[0], -1)
    ci = np.array([ci95(flat[:, j]) for j in range(flat.shape[1])]).reshape(*x.shape[1:], 2)
    return x.mean(axis=0), ci[..., 0], ci[..., 1]


@dataclass(frozen=True)
class LearnerResult:
    """One learner on the test flights, per training seed and scenario.

    Attributes
    ----------
    seeds : tuple of int
    rmse : ndarray, shape (seeds, scenarios)
        Mean RMSE over the flights [nT].
    score : ndarray, shape (seeds, scenarios)
        Normalized score (every scenario; :attr:`Benchmark.headroom` says which count).
    cvar : ndarray, shape (seeds, scenarios)
        Mean RMSE of the worst :data:`CVAR_FRACTION` of the flights [nT].
    worse : ndarray of bool, shape (seeds, scenarios)
        Worse than the tuned constant beyond the paired 95 % t interval over flights.
    excess : ndarray, shape (seeds, scenarios)
        Mean RMSE minus the tuned constant's on the same flights [nT].
    """

    seeds: tuple[int, ...]
    rmse: np.ndarray
    score: np.ndarray
    cvar: np.ndarray
    worse: np.ndarray
    excess: np.ndarray


@dataclass(frozen=True)
class Benchmark:
    """Every learner's :class:`LearnerResult` and the references on the same flights.

    Attributes
    ----------
    flights : FlightTable
    headroom : ndarray of bool, shape (scenarios,)
        ``privileged`` better than ``tuned_constant`` beyond the paired interval: the scenarios
        that are scored.
    reference_rmse, reference_cvar : dict of str to ndarray, shape (scenarios,)
        Each reference's mean RMSE and CVaR [nT].
    learners : dict of str to LearnerResult
    """

    flights: FlightTable
    headroom: np.ndarray
    reference_rmse: dict[str, np.ndarray]
    reference_cvar: dict[str, np.ndarray]
    learners: dict[str, LearnerResult]

    @property
    def scored(self) -> list[str]:
        """The scenarios with headroom."""
        return [s for s, h in zip(self.flights.scenarios, self.headroom, strict=True) if h]

    def scores(self) -> dict[str, np.ndarray]:
        """Each learner's normalized scores ``(seeds, scenarios with headroom)``: rliable's
        runs × tasks."""
        return {n: r.score[:, self.headroom] for n, r in self.learners.items()}


def benchmark(flights: FlightTable) -> Benchmark:
    """Every learner's per-seed statistics on ``flights``."""
    refs = flights.references
    zero, one = refs[SCORE_ZERO], refs[SCORE_ONE]
    learners = {
        name: LearnerResult(
            seeds=flights.seeds[name],
            rmse=r.mean(axis=-1),
            score=normalized_score(r.mean(axis=-1), zero.mean(axis=-1), one.mean(axis=-1)),
            cvar=cvar(r),
            worse=exceeds(r, zero),
            excess=(r - zero).mean(axis=-1),
        )
        for name, r in flights.learners.items()
    }
    return Benchmark(
        flights=flights,
        headroom=exceeds(zero, one),
        reference_rmse={n: r.mean(axis=-1) for n, r in refs.items()},
        reference_cvar={n: cvar(r) for n, r in refs.items()},
        learners=learners,
    )


# --- rliable ----------------------------------------------------------------------------------


@contextmanager
def _global_rng(seed: int) -> Iterator[None]:
    """numpy's global generator seeded, and restored after: rliable 1.2 draws its bootstrap
    indices with ``np.random.choice``, whatever ``random_state`` it is given (arch's warning that
    ``random_state`` is deprecated is silenced here)."""
    state = np.random.get_state()  # noqa: NPY002  (rliable's generator is the legacy one)
    np.random.seed(seed)  # noqa: NPY002
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", "random_state is deprecated", FutureWarning)
            yield
    finally:
        np.random.set_state(state)  # noqa: NPY002


def _intervals(
    data: Mapping[str, Any], func: Callable[..., Any], reps: int, seed: int
) -> dict[str, np.ndarray]:
    """rliable's stratified bootstrap: per key, ``(point, low, high)`` stacked on the first
    axis (shape ``(3, *func's output)``)."""
    from rliable import library as rly

    with _global_rng(seed):
        points, cis = rly.get_interval_estimates(
            dict(data), func, reps=reps, random_state=np.random.RandomState(seed)
        )
    return {
        k: np.concatenate([np.reshape(points[k], (1, -1)), np.reshape(cis[k], (2, -1))])
        for k in data
    }


def aggregates(
    scores: Mapping[str, np.ndarray], reps: int = BOOTSTRAP_RESAMPLES, seed: int = 0
) -> dict[str, np.ndarray]:
    """rliable's :data:`AGGREGATES` of each learner's normalized scores ``(seeds, scenarios)``
    with stratified-bootstrap 95 % intervals: per learner an array ``(3, 3)``, rows point,
    low, high; columns IQM, mean, optimality gap (the mean shortfall below 1)."""
    from rliable import metrics

    funcs = (metrics.aggregate_iqm, metrics.aggregate_mean, metrics.aggregate_optimality_gap)

    def func(x: np.ndarray) -> np.ndarray:
        return np.array([f(x) for f in funcs])

    return _intervals(scores, func, reps, seed)


def improvement_probability(x: np.ndarray, y: np.ndarray) -> float:
    """P(X > Y) over scenarios: rliable's ``metrics.probability_of_improvement`` (the
    Mann–Whitney U over pairs of runs, ties counting half, averaged over tasks), counted
    directly instead of through scipy's test, which is ~100× slower inside a bootstrap.

    Parameters
    ----------
    x, y : ndarray, shape (runs_x, tasks), (runs_y, tasks)
        Scores of the two algorithms.
    """
    a, b = x[:, None, :], y[None, :, :]
    return float(np.mean(np.mean(a > b, axis=(0, 1)) + 0.5 * np.mean(a == b, axis=(0, 1))))


def improvement(
    scores: Mapping[str, np.ndarray],
    baseline: str = BASELINE,
    reps: int = BOOTSTRAP_RESAMPLES,
    seed: int = 0,
) -> dict[str, np.ndarray]:
    """The probability that each learner's score beats ``baseline``'s on a scenario, with
    rliable's independent stratified-bootstrap interval: per learner ``(point, low, high)``.
    Empty without the baseline."""
    if baseline not in scores:
        return {}
    pairs = {n: (s, scores[baseline]) for n, s in scores.items() if n != baseline}
    return {k: v[:, 0] for k, v in _intervals(pairs, improvement_probability, reps, seed).items()}


def score_distribution(scores: np.ndarray, taus: np.ndarray) -> np.ndarray:
    """The fraction of runs × tasks whose score exceeds each ``tau``: rliable's performance
    profile (its ``score_distributions``), vectorised over ``taus``."""
    return np.mean(np.ravel(scores)[None, :] > np.asarray(taus)[:, None], axis=1)


def profiles(
    scores: Mapping[str, np.ndarray],
    taus: np.ndarray,
    reps: int = BOOTSTRAP_RESAMPLES,
    seed: int = 0,
) -> dict[str, np.ndarray]:
    """rliable's performance profiles (``create_performance_profile``, score distributions)
    at ``taus``: per learner ``(3, taus)``, rows point, low, high."""
    from rliable import library as rly

    with _global_rng(seed):
        points, cis = rly.create_performance_profile(
            dict(scores), taus, custom_profile_func=score_distribution, reps=reps
        )
    return {k: np.vstack([points[k], cis[k]]) for k in scores}


# --- the bar ----------------------------------------------------------------------------------


def at_most(x: float, y: float) -> bool:
    """``x ≤ y`` up to round-off (1e-12 relative): a mean over seeds of the tuned constant's own
    numbers is the tuned constant's, not one unit in the last place above it."""
    return bool(x <= y or np.isclose(x, y, rtol=1e-12, atol=0.0))


@dataclass(frozen=True)
class BarCheck:
    """Issue 41's bar for a shipped general policy, for one learner.

    Attributes
    ----------
    worse : list of (int, str, float)
        (a) Each (seed, scenario, mean excess [nT]) worse than the tuned constant beyond the
        paired 95 % interval over flights; met when empty.
    tail : list of (str, float, float)
        (b) Each (scenario, the learner's CVaR mean over seeds, the tuned constant's) [nT] where
        the learner's is higher; met when empty.
    nonstationary : tuple of (float, float)
        (c) Mean RMSE over seeds on :data:`BAR_SCENARIO` and the tuned constant's [nT]; met
        when the first is at most the second (NaN without the scenario: not met).
    iqm : ndarray, shape (3,)
        (d) IQM of the normalized score over seeds × scenarios with its interval; met when the
        point is at least :data:`BAR_IQM`.
    """

    worse: list[tuple[int, str, float]]
    tail: list[tuple[str, float, float]]
    nonstationary: tuple[float, float]
    iqm: np.ndarray

    @property
    def met(self) -> tuple[bool, bool, bool, bool]:
        """(a), (b), (c), (d)."""
        learner, tc = self.nonstationary
        return (not self.worse, not self.tail, at_most(learner, tc), bool(self.iqm[0] >= BAR_IQM))


def bar(result: Benchmark, learner: str, iqm: np.ndarray) -> BarCheck:
    """The bar's four checks for ``learner``; ``iqm`` is its ``(point, low, high)``."""
    r = result.learners[learner]
    names = result.flights.scenarios
    tc_cvar = result.reference_cvar[SCORE_ZERO]
    tc_rmse = result.reference_rmse[SCORE_ZERO]
    mean_cvar = r.cvar.mean(axis=0)
    worse = [
        (seed, names[k], float(r.excess[i, k]))
        for i, seed in enumerate(r.seeds)
        for k in range(len(names))
        if r.worse[i, k]
    ]
    tail = [
        (s, float(mean_cvar[k]), float(tc_cvar[k]))
        for k, s in enumerate(names)
        if not at_most(mean_cvar[k], tc_cvar[k])
    ]
    if BAR_SCENARIO in names:
        k = names.index(BAR_SCENARIO)
        ns = (float(r.rmse[:, k].mean()), float(tc_rmse[k]))
    else:
        ns = (math.nan, math.nan)
    return BarCheck(worse=worse, tail=tail, nonstationary=ns, iqm=np.asarray(iqm, dtype=float))


def closest(bars: Mapping[str, BarCheck]) -> str:
    """The learner nearest the bar: the most criteria met, then the highest IQM (a NaN IQM
    last)."""

    def rank(name: str) -> tuple[int, float]:
        iqm = float(bars[name].iqm[0])
        return sum(bars[name].met), iqm if math.isfinite(iqm) else -math.inf

    return max(bars, key=rank)


# --- learning curves --------------------------------------------------------------------------


@dataclass(frozen=True)
class Curve:
    """A learner's learning curve on the normalized scale, over its training seeds.

    Seeds validate every ``eval_every`` steps, so their k-th validation points match; the steps
    may differ where a point is the end of training or a CMA-ES generation overshoots. Points
    are matched by their order and placed at the mean of their steps and minutes.

    Attributes
    ----------
    timesteps : ndarray, shape (points,)
        Environment steps, mean over the seeds that have the point.
    minutes : ndarray, shape (points,)
        Wall-clock training minutes (validation excluded), mean over those seeds.
    seeds : ndarray of int, shape (points,)
        How many seeds have the point.
    score, low, high : ndarray, shape (points,)
        The validation score's mean over seeds and its 95 % t interval (NaN with one seed).
    """

    timesteps: np.ndarray
    minutes: np.ndarray
    seeds: np.ndarray
    score: np.ndarray
    low: np.ndarray
    high: np.ndarray


def validation_score(
    rmse: Mapping[str, float], anchors: Mapping[str, Mapping[str, float]]
) -> float:
    """A validation point's normalized score: the mean over scenarios of
    ``(tc − rmse) / (tc − privileged)`` on the anchors' mean RMSE on the same validation flights,
    scenarios whose headroom ``tc − privileged`` is not positive left out."""
    scores = [
        normalized_score(v, a[SCORE_ZERO], a[SCORE_ONE])
        for s, v in rmse.items()
        if (a := anchors[s])[SCORE_ZERO] - a[SCORE_ONE] > 0
    ]
    if not scores:
        raise AeromagError("no scenario of the validation flights has headroom for a score")
    return float(np.mean(scores))


def _validation_runs(
    rows: Iterable[Mapping[str, str]], anchors: Mapping[str, Mapping[str, Mapping[str, float]]]
) -> dict[str, dict[str, list[tuple[int, float, float]]]]:
    """learner → seed → its validation points ``(steps, training minutes, score)`` in order."""
    points: dict[tuple[str, str, int], dict[str, Any]] = {}
    for row in rows:
        key = (row["learner"], row["seed"], int(row["timesteps"]))
        p = points.setdefault(
            key, {"minutes": float(row["train_seconds"]) / 60, "flights": row["flights"]}
        )
        p.setdefault("rmse", {})[row["scenario"]] = float(row["validation_rmse_nt"])
    runs: dict[str, dict[str, list[tuple[int, float, float]]]] = defaultdict(dict)
    for (learner, seed, steps), p in sorted(points.items(), key=lambda kv: kv[0][2]):
        if p["flights"] not in anchors:
            raise AeromagError(f"runs.json has no validation anchors for {p['flights']} flights")
        score = validation_score(p["rmse"], anchors[p["flights"]])
        runs[learner].setdefault(seed, []).append((steps, p["minutes"], score))
    return runs


def learning_curves(
    rows: Iterable[Mapping[str, str]], anchors: Mapping[str, Mapping[str, Mapping[str, float]]]
) -> dict[str, Curve]:
    """Each learner's :class:`Curve` from ``curves.csv``'s rows (``learner, seed, timesteps,
    seconds, train_seconds, scenario, flights, validation_rmse_nt``); ``anchors`` is
    ``runs.json``'s ``validation_anchors`` (by the number of validation flights per scenario,
    as a string). Learners in the order of ``agents.training.learners.LEARNERS``."""
    runs = _validation_runs(rows, anchors)
    curves = {}
    for name in sorted(runs, key=_order):
        seeds = list(runs[name].values())
        # the k-th point of every seed that has one: (steps, minutes, score) × seeds
        at = [np.array([s[k] for s in seeds if k < len(s)]) for k in range(max(map(len, seeds)))]
        ci = np.array([ci95(p[:, 2]) for p in at])
        curves[name] = Curve(
            timesteps=np.array([p[:, 0].mean() for p in at]),
            minutes=np.array([p[:, 1].mean() for p in at]),
            seeds=np.array([len(p) for p in at]),
            score=np.array([p[:, 2].mean() for p in at]),
            low=ci[:, 0],
            high=ci[:, 1],
        )
    return curves
