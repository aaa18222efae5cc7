"""Joint evidence: a candidate group tested with the noise model re-fitted along with it.

The fixed-noise test (:mod:`~aeromag_env.discovery.evidence`) whitens with the noise model of
the residual *without* the candidate. A slow effect — a permanent-field drift following a
temperature, a field following a slowly wandering channel — was then taken in by that noise
model's slow part (its FOGM grew to fit it), and whitening removes most of it from the data and
from the candidate's columns alike: a 2-nT drift with p = 1.7e-5 showed ΔBIC −5.7 and was
written off as noise. Here the model with the candidate and the model without are each fitted by
maximum likelihood *jointly* with their own noise model, and the likelihood ratio decides:

* ``ℓ(model)`` is maximised by alternating the GLS coefficients under the current noise model
  and the noise model's maximum-likelihood fit to the residual (:data:`NULL_ROUNDS` and
  :data:`CANDIDATE_ROUNDS` rounds, from the current noise model); each half-step raises it.
* ``LR = 2 (ℓ₁ − ℓ₀)`` replaces the fixed-noise ``ΔRSS / σ²``: the p-value is χ² with the
  group's degrees of freedom, and the group has evidence when it passes Holm's correction and
  ``LR > 6 · dof`` (:data:`~aeromag_env.discovery.evidence.JOINT_PENALTY`, calibrated on null
  flights: the χ² reference is asymptotic and named slow spurious groups). The fixed-noise test's
  ΔBIC guard, ``LR > log(rows) · dof``, is not asked: ``p log(rows)`` — 640 for the 60 columns
  of the external-field splines on a 35-min flight — wrote off a slow field whose p was 1e-62
  and whose naming shrank the held-out gap 3×. ``ΔBIC = LR − p log(rows)`` is still reported.

Which groups are re-tested: the *slow* ones (a group that could absorb at least
:data:`~aeromag_env.discovery.noise_model.ABSORBABLE_SHARE` of the slow noise's variance) that
the fixed-noise test found some evidence for (``p`` below :data:`SCREEN_P`), whether they pass
it or not. A fast group (a switched load, the eddy time constant, the lag: T̈-like columns) keeps
its fixed-noise verdict: a slow noise model cannot have taken it in, and without the ΔBIC guard
a switched decoy load at p = 3e-4 was named. Slow groups then compete on the same footing: on a
nominal flight the external variation across the main field (no scalar base station records it)
entered as ``altitude_gradient`` — 3 columns that pass the fixed test and catch the step between
the box at 3000 m and the lines at 400 m — while the external-field splines, which fit the whole
slow field (held-out gap 2.6× smaller), were only ever tested against a noise model that had
taken that field in.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from aeromag_env.discovery.evidence import JOINT_TEST, best_of_families
from aeromag_env.discovery.noise_model import (
    ABSORBABLE_SHARE,
    NoiseModel,
    fit_noise,
    log_likelihood,
)
from aeromag_env.discovery.preparation import PreparedFlight
from aeromag_env.discovery.regressors import predict_all
from aeromag_env.discovery.whitened_problem import WhitenedProblem
from aeromag_env.simulation.effects import Group

#: Alternations of the GLS fit and the noise model's maximum-likelihood fit: two for the model
#: without a candidate (fitted once per step), one for each candidate (a lower bound of its
#: maximum, so its ratio errs low, towards not naming; it is the costly part).
NULL_ROUNDS = 2
CANDIDATE_ROUNDS = 1
#: A slow group whose fixed-noise p-value is below this is re-tested jointly.
SCREEN_P = 0.01


def profile_likelihood(
    prob: WhitenedProblem, chosen: list[int], start: NoiseModel, rounds: int = NULL_ROUNDS
) -> tuple[float, NoiseModel]:
    """Log-likelihood of the model ``chosen`` (base first) maximised jointly over its GLS
    coefficients and its noise model, from ``start``, in ``rounds`` alternations; and that
    noise model."""
    noise = start
    for _ in range(rounds):
        beta = prob.gls(chosen, noise)
        resid = prob.residual(chosen, beta)
        noise = fit_noise(resid, prob.gap, start=noise)
    return log_likelihood(resid, prob.gap, noise), noise


class JointTests:
    """Joint likelihood-ratio statistics of candidate groups against one model (cached).

    Parameters
    ----------
    prob : WhitenedProblem
        The problem; its current noise model is the starting point of every joint fit.
    chosen : list of int
        Problem indices of the model the candidates are added to, base (0) first.
    """

    def __init__(self, prob: WhitenedProblem, chosen: list[int]) -> None:
        assert prob.noise is not None
        self.prob, self.chosen = prob, list(chosen)
        self._null: tuple[float, NoiseModel] | None = None

    def null(self) -> tuple[float, NoiseModel]:
        """Joint log-likelihood and noise model of the model without a candidate."""
        if self._null is None:
            assert self.prob.noise is not None
            self._null = profile_likelihood(self.prob, self.chosen, self.prob.noise)
        return self._null

    def statistics(self, candidate: int, fixed: dict[str, float]) -> dict[str, Any]:
        """``fixed`` (the candidate's fixed-noise statistics) with the joint test's p-value and
        ΔBIC in place: ``lr_statistic``, ``p_value``, ``log10_p_value``, ``delta_bic``,
        ``test = "joint noise model"``."""
        from scipy.stats import chi2

        ll0, noise0 = self.null()
        ll1, _ = profile_likelihood(self.prob, [*self.chosen, candidate], noise0, CANDIDATE_ROUNDS)
        lr = max(2.0 * (ll1 - ll0), 0.0)
        p = int(fixed["dof"])
        rows = 3 * self.prob.idx.size
        return {
            **fixed,
            "lr_statistic": lr,
            "p_value": float(chi2.sf(lr, p)),
            "log10_p_value": max(float(chi2.logsf(lr, p) / math.log(10.0)), -300.0),
            "delta_bic": lr - p * math.log(rows),
            "test": JOINT_TEST,
        }


def needs_joint(prob: WhitenedProblem, chosen: list[int], j: int, stats: dict[str, float]) -> bool:
    """Whether group ``j``'s fixed-noise verdict is re-tested jointly (see the module notes)."""
    if stats["p_value"] >= SCREEN_P:
        return False
    assert prob.noise is not None
    share = prob.absorbable_share(chosen, j, prob.noise.fogm_tau_s[None, :])
    return bool(share.max() >= ABSORBABLE_SHARE)


def retest(
    prob: WhitenedProblem,
    chosen: list[int],
    tests: dict[int, dict[str, float]],
    profiled: dict[int, bool],
) -> dict[int, dict[str, Any]]:
    """``tests`` with every group :func:`needs_joint` selects replaced by its joint statistics.

    Parameters
    ----------
    prob : WhitenedProblem
        The problem, with the noise model of ``chosen`` set.
    chosen : list of int
        The model the groups are tested against, base first.
    tests : dict
        Fixed-noise statistics per problem index.
    profiled : dict
        Per problem index, whether the group belongs to a profiled family.
    """
    joint: JointTests | None = None
    out: dict[int, dict[str, Any]] = dict(tests)
    for j, t in tests.items():
        if not profiled[j] and needs_joint(prob, chosen, j, t):
            joint = joint or JointTests(prob, chosen)
            out[j] = joint.statistics(j, t)
    return out


def held_out_veto(
    prob: WhitenedProblem,
    data: PreparedFlight,
    columns: list[np.ndarray],
    chosen: list[int],
    evidence: dict[int, dict[str, Any]],
) -> tuple[list[int], list[int]]:
    """Drop every group named by the joint test whose naming does not predict the held-out part
    better: the model re-fitted without it must leave a larger held-out residual than with it.

    The χ² reference of the likelihood ratio is asymptotic, and a 54-column spline group beside a
    fitted FOGM is far from it: after a sensor lag at SNR 4 the splines passed at p = 3e-5 and
    made the held-out residual 28 % larger. Held-out prediction (every third 60-s block, never
    fitted) is the check that needs no asymptotics; it can only remove an effect, so the reported
    gap is at most that much flattered.

    Parameters
    ----------
    prob : WhitenedProblem
        The problem, with the selected model's noise model set.
    data : PreparedFlight
        The prepared flight (measured field and held-out mask).
    columns : list of numpy.ndarray
        Regressor groups (n, 3, p) on all samples, indexed like the problem (0: the base).
    chosen : list of int
        The selected model, base first.
    evidence : dict
        Statistics of each chosen group; those with ``test`` :data:`JOINT_TEST` are checked.

    Returns
    -------
    tuple of (list of int, list of int)
        The model kept, and the groups vetoed (their evidence gains ``held_out_veto``).
    """
    vetoed: list[int] = []
    for j in [c for c in chosen[1:] if evidence.get(c, {}).get("test") == JOINT_TEST]:
        others = [c for c in chosen if c != j]
        with_j, without = (_held_out_rms(prob, data, columns, m) for m in (chosen, others))
        if with_j >= without:
            evidence[j]["held_out_veto"] = {"rms_with_nt": with_j, "rms_without_nt": without}
            chosen, vetoed = others, [*vetoed, j]
    return chosen, vetoed


def _held_out_rms(
    prob: WhitenedProblem, data: PreparedFlight, columns: list[np.ndarray], chosen: list[int]
) -> float:
    """Raw RMS of measured − model on the held-out samples, the model GLS-fitted on the rest."""
    beta, _ = prob.fit(chosen)
    r = data.y[data.held_out] - predict_all([columns[j] for j in chosen], beta, data.held_out)
    return float(np.sqrt(np.mean(r**2)))


def step_tests(
    prob: WhitenedProblem, groups: list[Group], chosen: list[int], remaining: list[int]
) -> dict[int, dict[str, Any]]:
    """A forward step's statistics: each remaining family's best group against ``chosen``,
    fixed-noise, or joint where :func:`retest` re-tests it (problem index ``j`` is
    ``groups[j − 1]``)."""
    live = best_of_families(groups, {j: prob.test(chosen, j) for j in remaining})
    return retest(prob, chosen, live, {j: groups[j - 1].profile is not None for j in live})
