"""The statistics of an evaluation: t intervals of the mean, the paired differences against
``fis``, the normalized score with its paired bootstrap interval, and the interquartile mean
over training seeds × scenarios with its stratified bootstrap interval."""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import stats

#: The normalized score's anchors: 0 is the best constant tuning found offline, 1 the policy
#: that knows the true noise and the steps (``privileged``); score = (RMSE₀ − RMSE) /
#: (RMSE₀ − RMSE₁).
SCORE_ZERO, SCORE_ONE = "tuned_constant", "privileged"
#: Paired bootstrap resamples of the flights for the normalized score's interval.
BOOTSTRAP_RESAMPLES = 2000


def ci95(x: np.ndarray) -> list[float]:
    """The 95 % t interval of the mean of ``x`` (NaN, NaN with fewer than 2 values)."""
    if x.size < 2:
        return [float("nan"), float("nan")]
    half = stats.t.ppf(0.975, x.size - 1) * x.std(ddof=1) / np.sqrt(x.size)
    return [float(x.mean() - half), float(x.mean() + half)]


def normalized_scores(per: dict[str, dict[str, np.ndarray]]) -> dict[str, Any] | None:
    """Each policy's normalized score (0 = :data:`SCORE_ZERO`, 1 = :data:`SCORE_ONE`, on mean
    RMSE) with a paired 95 % percentile-bootstrap interval over the flights (scipy), and
    ``anchors``: the headroom ``RMSE₀ − RMSE₁`` with its paired t interval. None without both
    anchors or with fewer than 2 flights; scores None, with a note, when the headroom's
    interval does not lie above 0 (the privileged policy is not better on these flights)."""
    if SCORE_ZERO not in per or SCORE_ONE not in per or per[SCORE_ZERO]["rmse_nt"].size < 2:
        return None
    zero, one = per[SCORE_ZERO]["rmse_nt"], per[SCORE_ONE]["rmse_nt"]
    headroom = zero - one  # paired: same flights
    anchors: dict[str, Any] = {
        "zero": SCORE_ZERO,
        "one": SCORE_ONE,
        "headroom_nt_mean": float(headroom.mean()),
        "headroom_nt_ci95": ci95(headroom),
        "note": None,
    }
    out: dict[str, Any] = {"anchors": anchors}
    if not anchors["headroom_nt_ci95"][0] > 0:
        anchors["note"] = (
            f"no headroom: {SCORE_ONE} is not better than {SCORE_ZERO} beyond "
            "the interval on these flights, so no score is defined"
        )
        return {
            **out,
            **{
                name: {"normalized_score": None, "normalized_score_ci95": [None, None]}
                for name in per
            },
        }

    def score(z: np.ndarray, o: np.ndarray, p: np.ndarray, axis: int = -1) -> np.ndarray:
        z_mean = z.mean(axis=axis)
        with np.errstate(divide="ignore", invalid="ignore"):  # a resample without headroom
            return (z_mean - p.mean(axis=axis)) / (z_mean - o.mean(axis=axis))

    for name, v in per.items():
        rmse = v["rmse_nt"]
        boot = stats.bootstrap(
            (zero, one, rmse),
            score,
            paired=True,
            vectorized=True,
            n_resamples=BOOTSTRAP_RESAMPLES,
            method="percentile",
            rng=0,
        )
        ci = [float(boot.confidence_interval.low), float(boot.confidence_interval.high)]
        out[name] = {"normalized_score": float(score(zero, one, rmse)), "normalized_score_ci95": ci}
    return out


def policy_summaries(per: dict[str, dict[str, np.ndarray]]) -> dict[str, dict[str, Any]]:
    """Each policy's ``results.json`` row: mean RMSE [nT] with its t interval, reward, divergences,
    outlier rejections, median |log10 ROR|, the per-flight RMSEs and, with ``fis`` among them,
    the paired difference against it."""
    ref = per.get("fis")
    out = {}
    for name, v in per.items():
        row = {
            "rmse_nt_mean": float(v["rmse_nt"].mean()),
            "rmse_nt_ci95": ci95(v["rmse_nt"]),
            "reward_mean": float(v["reward"].mean()),
            "divergences": int(v["divergences"].sum()),
            "outliers_rejected": int(v["outliers_rejected"].sum()),
            "log_ror_abs_median": float(np.nanmedian(v["log_ror_abs_median"])),
            "rmse_nt": v["rmse_nt"].tolist(),
        }
        if ref is not None:
            diff = v["rmse_nt"] - ref["rmse_nt"]  # paired: same flights
            row["diff_vs_fis_nt_mean"] = float(diff.mean())
            row["diff_vs_fis_ci95"] = ci95(diff)
        out[name] = row
    return out


def iqm_interval(
    scores: np.ndarray, reps: int = BOOTSTRAP_RESAMPLES, seed: int = 0
) -> tuple[float, list[float]]:
    """Interquartile mean of normalized scores ``(runs, tasks)`` (training seeds × scenarios)
    and its 95 % stratified-bootstrap percentile interval: runs are resampled with replacement
    within each task, as rliable's ``get_interval_estimates`` does (Agarwal et al. 2021). The
    IQM is scipy's 25 %-trimmed mean of all scores, which is rliable's ``metrics.aggregate_iqm``
    (``tests/agents/test_benchmark.py`` checks that they agree); rliable itself is a dev extra
    (its 1.2 release needs pandas < 3 and arch < 8), not needed here."""
    scores = np.asarray(scores, dtype=float)
    if scores.ndim != 2 or scores.shape[0] < 1:
        raise ValueError(f"scores must be (runs, tasks), got shape {scores.shape}")
    runs, tasks = scores.shape
    point = float(stats.trim_mean(scores.ravel(), 0.25))
    if runs < 2:
        return point, [float("nan"), float("nan")]
    rng = np.random.default_rng(seed)
    picks = rng.integers(0, runs, (reps, runs, tasks))  # per task, its own resample of the runs
    resampled = np.take_along_axis(scores[None, :, :], picks, axis=1).reshape(reps, -1)
    boot = stats.trim_mean(resampled, 0.25, axis=1)
    low, high = np.percentile(boot, [2.5, 97.5])
    return point, [float(low), float(high)]
