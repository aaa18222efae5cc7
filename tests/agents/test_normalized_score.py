"""The normalized score of ``aeromag evaluate`` (issue 21): 0 = tuned_constant, 1 = privileged
(knows the noise and the steps), on mean RMSE over the same flights, with a paired bootstrap
interval (scipy).

The independent truths are the definition (the anchors score 0 and 1 exactly; a policy whose
RMSE is the anchors' mean on every flight scores 0.5 with a zero-width interval) and a
hand-rolled paired bootstrap of the same statistic.
"""

from __future__ import annotations

import numpy as np
import pytest

from aeromag_env.jobs.evaluate import evaluation_table
from agents.evaluation.statistics import BOOTSTRAP_RESAMPLES, normalized_scores, policy_summaries


def _per(**rmse: np.ndarray) -> dict[str, dict[str, np.ndarray]]:
    n = len(next(iter(rmse.values())))
    zeros = np.zeros(n)
    return {
        name: {
            "rmse_nt": r,
            "reward": -r,
            "divergences": zeros,
            "outliers_rejected": zeros,
            "log_ror_abs_median": zeros,
        }
        for name, r in rmse.items()
    }


def _flights(seed: int = 0, n: int = 30) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    base = rng.uniform(1.0, 5.0, n)  # flights differ far more than the policies
    return {
        "tuned_constant": base + 1.0 + rng.normal(0, 0.1, n),
        "privileged": base,
        "fis": base + 2.0 + rng.normal(0, 0.3, n),
    }


def test_the_anchors_score_zero_and_one_and_the_midpoint_half():
    f = _flights()
    f["half"] = (f["tuned_constant"] + f["privileged"]) / 2
    scores = normalized_scores(_per(**f))
    assert scores is not None
    assert scores["tuned_constant"]["normalized_score"] == 0.0
    assert scores["privileged"]["normalized_score"] == 1.0
    assert scores["half"]["normalized_score"] == pytest.approx(0.5, abs=1e-12)
    assert scores["half"]["normalized_score_ci95"] == pytest.approx([0.5, 0.5], abs=1e-12)
    assert scores["fis"]["normalized_score"] < 0  # worse than the tuned constant
    lo, hi = scores["fis"]["normalized_score_ci95"]
    assert lo < scores["fis"]["normalized_score"] < hi < 0
    assert scores["anchors"]["headroom_nt_ci95"][0] > 0 and scores["anchors"]["note"] is None


@pytest.mark.parametrize("seed", range(3))
def test_the_interval_is_a_paired_bootstrap_of_the_flights(seed):
    """A paired percentile bootstrap written out with numpy gives the same interval to within
    its Monte Carlo error (2000 resamples each)."""
    f = _flights(seed)
    lo, hi = normalized_scores(_per(**f))["fis"]["normalized_score_ci95"]
    rng = np.random.default_rng(seed + 100)
    idx = rng.integers(0, 30, (BOOTSTRAP_RESAMPLES, 30))
    z, o, p = (f[k][idx].mean(axis=1) for k in ("tuned_constant", "privileged", "fis"))
    want = np.percentile((z - p) / (z - o), [2.5, 97.5])
    width = want[1] - want[0]
    assert abs(lo - want[0]) < 0.1 * width and abs(hi - want[1]) < 0.1 * width


def test_no_headroom_gives_no_score_and_says_why():
    f = _flights()
    f["privileged"] = f["tuned_constant"] + np.random.default_rng(1).normal(0, 0.05, 30)
    scores = normalized_scores(_per(**f))
    assert all(scores[k]["normalized_score"] is None for k in f)
    assert scores["anchors"]["note"].startswith("no headroom: privileged is not better")


def test_without_both_anchors_or_with_one_flight_there_is_no_score():
    f = _flights()
    assert normalized_scores(_per(fis=f["fis"], privileged=f["privileged"])) is None
    assert normalized_scores(_per(**{k: v[:1] for k, v in f.items()})) is None


def test_the_table_shows_the_score_column_and_the_anchors():
    f = _flights()
    per = _per(**f)
    scores = normalized_scores(per)
    results = {
        "scenario": "x",
        "seeds": list(range(30)),
        "policies": policy_summaries(per),
        "normalized_score": scores.pop("anchors"),
    }
    for name, row in scores.items():
        results["policies"][name].update(row)
    table = evaluation_table(results)
    assert "normalized score (95 % CI) |" in table and "| privileged |" in table
    assert "0 = tuned_constant, 1 = privileged (headroom 1" in table
    assert table.count(" 1 [1, 1] |") == 1 and table.count(" 0 [0, 0] |") == 1


def test_the_iqm_is_the_quarter_trimmed_mean_with_a_stratified_interval():
    from scipy import stats

    from agents.evaluation.statistics import iqm_interval

    rng = np.random.default_rng(3)
    scores = rng.normal(0.7, 0.1, (5, 3))
    point, (lo, hi) = iqm_interval(scores)
    assert point == pytest.approx(stats.trim_mean(scores.ravel(), 0.25))
    assert lo < point < hi
    # a loop over resamples, each task's runs drawn on their own: the same interval to within
    # the Monte Carlo error
    boots = []
    for _ in range(BOOTSTRAP_RESAMPLES):
        cols = [scores[rng.integers(0, 5, 5), t] for t in range(3)]
        boots.append(stats.trim_mean(np.concatenate(cols), 0.25))
    want = np.percentile(boots, [2.5, 97.5])
    assert abs(lo - want[0]) < 0.1 * (want[1] - want[0])
    assert abs(hi - want[1]) < 0.1 * (want[1] - want[0])


def test_the_bootstrap_keeps_each_task_s_runs_in_their_task():
    """Task A scores 0 on every run, task B 1: any stratified resample holds four of each, so
    the IQM is 0.5 with no spread (an unstratified one would move)."""
    from agents.evaluation.statistics import iqm_interval

    scores = np.column_stack([np.zeros(4), np.ones(4)])
    assert iqm_interval(scores) == (0.5, [0.5, 0.5])
    assert np.isnan(iqm_interval(scores[:1])[1]).all()
    with pytest.raises(ValueError, match=r"\(runs, tasks\)"):
        iqm_interval(np.zeros(4))
