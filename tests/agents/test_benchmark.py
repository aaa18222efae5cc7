"""The learners' benchmark statistics (``agents.comparison.statistics``) on hand-made numbers whose
answers are known, and rliable (Agarwal et al. 2021) as the independent reference of the aggregates:
our IQM (``agents.evaluation.statistics.iqm_interval``) and the vectorised probability of
improvement and
performance profile give rliable's numbers, bootstrap intervals included."""

from __future__ import annotations

import numpy as np
import pytest
from rliable import library as rly
from rliable import metrics

from aeromag_env.errors import AeromagError
from agents.comparison import statistics as bm
from agents.evaluation.statistics import iqm_interval
from tests._helpers import assert_one_line_error

SCENARIOS = ("paper", "nonstationary", "noise_bursts")


def _rows(rmse: dict[tuple[str, str], np.ndarray], first: int = 200_000) -> list[dict[str, str]]:
    """``flights.csv`` rows of ``(learner, seed) → RMSE (scenarios, flights)``."""
    return [
        {
            "learner": name,
            "seed": seed,
            "scenario": s,
            "flight": str(first + f),
            "rmse_nt": repr(float(v)),
        }
        for (name, seed), r in rmse.items()
        for k, s in enumerate(SCENARIOS)
        for f, v in enumerate(r[k])
    ]


def _anchors(n: int = 12, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """tuned_constant and privileged on ``n`` flights of each scenario: 1 nT of headroom."""
    rng = np.random.default_rng(seed)
    base = rng.uniform(1.0, 5.0, (len(SCENARIOS), n))
    return base + 1.0 + rng.normal(0, 0.1, base.shape), base


# --- per flight and per seed --------------------------------------------------------------------


def test_cvar_is_the_mean_of_the_worst_tenth_and_at_least_one_flight() -> None:
    assert bm.cvar(np.arange(1.0, 11.0)) == 10.0
    # 30 flights: the worst 3 (0.1 × 30 is 3.0000000000000004 in floating point, not 4)
    assert bm.cvar(np.arange(1.0, 31.0)) == pytest.approx(29.0, abs=1e-12)
    assert bm.cvar(np.array([3.0, 1.0, 2.0])) == 3.0  # fewer than 10 flights: the worst one
    rows = bm.cvar(np.array([[1.0, 5.0] * 5, [2.0] * 10]))
    np.testing.assert_array_equal(rows, [5.0, 2.0])


def test_the_anchors_score_0_and_1_and_the_midpoint_half() -> None:
    zero, one = np.array([3.0, 10.0]), np.array([1.0, 4.0])
    np.testing.assert_array_equal(bm.normalized_score(zero, zero, one), [0.0, 0.0])
    np.testing.assert_array_equal(bm.normalized_score(one, zero, one), [1.0, 1.0])
    np.testing.assert_array_equal(bm.normalized_score((zero + one) / 2, zero, one), [0.5, 0.5])


def test_exceeds_is_the_paired_t_interval_above_zero() -> None:
    rng = np.random.default_rng(1)
    y = rng.uniform(1, 5, (2, 20))
    assert not bm.exceeds(y, y).any()  # identical: the interval is [0, 0]
    assert bm.exceeds(y + 1.0 + rng.normal(0, 0.1, y.shape), y).all()
    assert not bm.exceeds(y + rng.normal(0, 1.0, y.shape) * [[0], [1]], y).any()
    assert not bm.exceeds(np.array([5.0]), np.array([1.0]))  # one flight: no interval


def test_flight_table_orders_learners_and_refuses_other_flights() -> None:
    zero, one = _anchors(n=4)
    table = bm.flight_table(
        _rows(
            {
                ("sac", "1"): zero,
                ("sac", "0"): one,
                ("ppo", "0"): zero,
                ("tuned_constant", ""): zero,
                ("privileged", ""): one,
            }
        )
    )
    assert list(table.learners) == ["ppo", "sac"]  # agents.training.learners.LEARNERS' order
    assert table.seeds["sac"] == (0, 1)
    np.testing.assert_array_equal(table.learners["sac"][0], one)
    assert table.scenarios == SCENARIOS and table.flights.shape == (3, 4)
    rows = _rows({("tuned_constant", ""): zero, ("privileged", ""): one})
    rows += _rows({("ppo", "0"): zero}, first=300_000)
    with pytest.raises(AeromagError) as e:
        bm.flight_table(rows)
    assert_one_line_error(e, "ppo seed 0", "tuned constant's flights", "paper")
    with pytest.raises(AeromagError) as e:
        bm.flight_table(_rows({("tuned_constant", ""): zero}))
    assert_one_line_error(e, "privileged")


def _benchmark(learners: dict[str, np.ndarray], n: int = 12) -> bm.Benchmark:
    """A benchmark of ``learners`` (name → RMSE ``(seeds, scenarios, flights)`` [nT]) beside
    :func:`_anchors`."""
    zero, one = _anchors(n)
    rmse = {("tuned_constant", ""): zero, ("privileged", ""): one}
    for name, r in learners.items():
        rmse.update({(name, str(seed)): r[seed] for seed in range(len(r))})
    return bm.benchmark(bm.flight_table(_rows(rmse)))


def test_a_learner_equal_to_the_tuned_constant_meets_all_but_the_iqm() -> None:
    zero, one = _anchors()
    result = _benchmark({"cmaes": np.array([zero] * 3), "ppo": np.array([one] * 3)})
    assert result.headroom.all()
    np.testing.assert_allclose(result.learners["cmaes"].score, 0.0, atol=1e-12)
    np.testing.assert_allclose(result.learners["ppo"].score, 1.0, atol=1e-12)
    equal = bm.bar(result, "cmaes", np.array([0.0, 0.0, 0.0]))
    assert equal.met == (True, True, True, False)  # "at most": equal passes (c)
    assert equal.nonstationary[0] == equal.nonstationary[1]
    assert bm.bar(result, "ppo", np.array([1.0, 1.0, 1.0])).met == (True, True, True, True)


def test_the_bar_names_the_seed_and_the_scenario_that_fail() -> None:
    zero, one = _anchors()
    bad = np.array([one, one, one])
    bad[2, 2] = zero[2] + 0.5  # seed 2 is worse than tc on noise_bursts
    tail = np.array([one] * 3)
    tail[:, 1, :3] = zero[1, :3] + 20.0  # three bad nonstationary flights in every seed
    result = _benchmark({"sac": bad, "tqc": tail})
    sac = bm.bar(result, "sac", np.array([0.8, 0.7, 0.9]))
    assert sac.met == (False, True, True, True)
    assert [(s, sc) for s, sc, _ in sac.worse] == [(2, "noise_bursts")]
    assert sac.worse[0][2] == pytest.approx(0.5)
    tqc = bm.bar(result, "tqc", np.array([0.5, 0.4, 0.6]))
    assert tqc.met[1:] == (False, False, False)
    assert [s for s, _, _ in tqc.tail] == ["nonstationary"]


def test_the_closest_learner_meets_most_criteria_then_has_the_highest_iqm() -> None:
    zero, one = _anchors()
    bad = np.array([one, one])
    bad[1, 0] = zero[0] + 3.0  # fails (a), and (b) on paper
    result = _benchmark({"sac": bad, "cmaes": np.array([zero] * 2), "tqc": np.array([zero] * 2)})
    bars = {
        "sac": bm.bar(result, "sac", np.array([0.9, 0.8, 1.0])),  # 2 of 4
        "cmaes": bm.bar(result, "cmaes", np.array([0.1, 0.0, 0.2])),  # 3 of 4
        "tqc": bm.bar(result, "tqc", np.array([0.2, 0.1, 0.3])),  # 3 of 4, a higher IQM
    }
    assert [sum(b.met) for b in bars.values()] == [2, 3, 3]
    assert bm.closest(bars) == "tqc"
    bars["tqc"] = bm.bar(result, "tqc", np.full(3, np.nan))  # no scores: (d) not met, ranked last
    assert bm.closest(bars) == "cmaes"


def test_a_scenario_without_headroom_is_not_scored() -> None:
    zero, one = _anchors()
    result = _benchmark({"ppo": np.array([one] * 2)})
    assert result.scored == list(SCENARIOS)
    same = bm.benchmark(
        bm.flight_table(
            _rows(
                {
                    ("tuned_constant", ""): zero,
                    ("privileged", ""): np.where(np.arange(3)[:, None] == 1, zero + 0.1, one),
                    ("ppo", "0"): one,
                }
            )
        )
    )
    assert same.scored == ["paper", "noise_bursts"]
    assert same.scores()["ppo"].shape == (1, 2)


def test_over_seeds_is_the_mean_and_t_interval() -> None:
    x = np.array([[1.0, 2.0], [3.0, 2.0], [2.0, 2.0]])
    mean, low, high = bm.over_seeds(x)
    np.testing.assert_array_equal(mean, [2.0, 2.0])
    half = 4.302652730 * 1.0 / np.sqrt(3)  # t(0.975, 2) from a table × SD 1 / √3
    np.testing.assert_allclose([low[0], high[0]], [2.0 - half, 2.0 + half], rtol=1e-9)
    assert low[1] == high[1] == 2.0


# --- rliable ------------------------------------------------------------------------------------


def _scores(seed: int = 3) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    out = {n: rng.normal(m, 0.3, (5, 7)) for n, m in (("ppo", 0.5), ("sac", 0.7), ("tqc", 0.5))}
    out["cmaes"] = out["ppo"].copy()  # ties everywhere: P = 0.5
    out["recurrent_ppo"] = rng.normal(0.6, 0.3, (3, 7))  # fewer seeds
    return out


def test_our_iqm_is_rlibles() -> None:
    for name, s in _scores().items():
        ours, _ = iqm_interval(s)
        assert ours == pytest.approx(float(metrics.aggregate_iqm(s)), abs=1e-12), name
        assert bm.aggregates({name: s}, reps=20)[name][0, 0] == pytest.approx(ours, abs=1e-12)


def test_aggregates_are_rliables_and_deterministic() -> None:
    scores = _scores()
    before = np.random.get_state()[1].copy()  # noqa: NPY002
    a = bm.aggregates(scores, reps=200)
    np.testing.assert_array_equal(np.random.get_state()[1], before)  # noqa: NPY002
    b = bm.aggregates(scores, reps=200)
    for name, s in scores.items():
        np.testing.assert_array_equal(a[name], b[name])
        assert a[name].shape == (3, 3)
        point = [metrics.aggregate_iqm(s), np.mean(s), np.mean(np.clip(1 - s, 0, None))]
        np.testing.assert_allclose(a[name][0], point, rtol=1e-12)
        assert (a[name][1] <= a[name][0]).all() and (a[name][0] <= a[name][2]).all()


def test_probability_of_improvement_is_rliables_with_its_interval() -> None:
    scores = _scores()
    for s in scores.values():
        ours = bm.improvement_probability(s, scores["ppo"])
        assert ours == pytest.approx(metrics.probability_of_improvement(s, scores["ppo"]), 1e-12)
    assert bm.improvement_probability(scores["cmaes"], scores["ppo"]) == 0.5
    ours = bm.improvement({n: scores[n] for n in ("ppo", "sac", "recurrent_ppo")}, reps=30)
    np.random.seed(0)  # noqa: NPY002  (rliable resamples with the global generator)
    pairs = {n: (scores[n], scores["ppo"]) for n in ("sac", "recurrent_ppo")}
    points, cis = rly.get_interval_estimates(pairs, metrics.probability_of_improvement, reps=30)
    for name in pairs:
        np.testing.assert_allclose(ours[name], [points[name], *np.ravel(cis[name])], rtol=1e-12)
    assert bm.improvement({"sac": scores["sac"]}) == {}  # no PPO runs


def test_profiles_are_rliables_with_their_interval() -> None:
    scores = {n: s for n, s in _scores().items() if n in ("ppo", "sac")}
    taus = np.linspace(-0.5, 1.5, 9)
    ours = bm.profiles(scores, taus, reps=30)
    np.random.seed(0)  # noqa: NPY002
    points, cis = rly.create_performance_profile(scores, taus, reps=30)
    for name in scores:
        np.testing.assert_allclose(ours[name], np.vstack([points[name], cis[name]]), rtol=1e-12)


# --- learning curves ----------------------------------------------------------------------------


def _curve_rows(learner: str, seed: int, steps: list[int], scores: list[float]) -> list[dict]:
    """Validation points of one run: on each scenario the RMSE that scores ``score``; on
    ``noise_bursts`` (no validation headroom) a nonsense RMSE that must not count."""
    tc, priv = {"paper": 3.0, "nonstationary": 5.0}, {"paper": 2.0, "nonstationary": 3.0}
    rows = []
    for k, (t, score) in enumerate(zip(steps, scores, strict=True)):
        rmse = {s: tc[s] - score * (tc[s] - priv[s]) for s in tc} | {"noise_bursts": 1e6}
        rows += [
            {
                "learner": learner,
                "seed": str(seed),
                "timesteps": str(t),
                "seconds": str(70.0 * (k + 1)),
                "train_seconds": str(60.0 * (k + 1)),
                "scenario": s,
                "flights": "4",
                "validation_rmse_nt": repr(float(v)),
            }
            for s, v in rmse.items()
        ]
    return rows


ANCHORS = {
    "4": {
        "paper": {"tuned_constant": 3.0, "privileged": 2.0},
        "nonstationary": {"tuned_constant": 5.0, "privileged": 3.0},
        "noise_bursts": {"tuned_constant": 2.0, "privileged": 2.5},
    }
}


def test_learning_curves_match_points_by_order_and_average_seeds() -> None:
    rows = _curve_rows("sac", 0, [25_000, 50_000, 60_100], [0.1, 0.3, 0.5])
    rows += _curve_rows("sac", 1, [25_000, 50_000, 60_300], [0.3, 0.5, 0.9])
    rows += _curve_rows("ppo", 0, [10_000], [0.2])
    curves = bm.learning_curves(rows, ANCHORS)
    assert list(curves) == ["ppo", "sac"]
    c = curves["sac"]
    np.testing.assert_allclose(c.score, [0.2, 0.4, 0.7], rtol=1e-12)
    np.testing.assert_array_equal(c.timesteps, [25_000, 50_000, 60_200])
    np.testing.assert_allclose(c.minutes, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(c.seeds, [2, 2, 2])
    half = 12.70620474 * np.std([0.1, 0.3], ddof=1) / np.sqrt(2)  # t(0.975, 1) from a table
    np.testing.assert_allclose([c.low[0], c.high[0]], [0.2 - half, 0.2 + half], rtol=1e-9)
    assert np.isnan(curves["ppo"].low[0])  # one seed: no interval


def test_a_curve_without_anchors_for_its_flights_is_refused() -> None:
    rows = _curve_rows("sac", 0, [25_000], [0.1])
    with pytest.raises(AeromagError) as e:
        bm.learning_curves(rows, {"7": ANCHORS["4"]})
    assert_one_line_error(e, "validation anchors", "4")
