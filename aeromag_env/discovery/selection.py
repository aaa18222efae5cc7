"""Model selection: which candidate groups enter the model, which stay, and the noise model.

Decides the augmented model. Forward selection: each remaining group gets a partial F-test on
the whitened problem; a group has evidence when it passes Holm's correction *and* its ΔBIC is
positive (:func:`~aeromag_env.discovery.evidence.significant`), or, re-tested with the noise
model fitted jointly (:func:`~aeromag_env.discovery.joint.retest`), its likelihood-ratio test
passes Holm's correction; the strongest by p-value is added, and the search repeats until none
has evidence (at most :data:`MAX_EFFECTS`). Groups
that differ only in a non-linear parameter (the eddy time constant, the lag) are profiled: the
best grid value competes with one more degree of freedom, and is refined between its grid
neighbours once it enters (:func:`refine`). After each entry the noise model is re-fitted; its
coloured part may shrink only where the entered group cannot have absorbed it
(:func:`~aeromag_env.discovery.noise_model.ratchet`). A chosen ``sensor_lag`` shifts the whole
modelled signal — Earth field, base aircraft field and the other named additive effects — not
the Earth field alone (:func:`lag_on_signal`). A backward pass then drops any named effect
without evidence (same rule, Holm over the named ones) given all the others (:func:`backward`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from aeromag_env.discovery.base_model import base_columns
from aeromag_env.discovery.evidence import (
    group_statistics,
    rounded,
    significant,
    strength,
)
from aeromag_env.discovery.joint import held_out_veto, retest, step_tests
from aeromag_env.discovery.noise_model import NoiseModel, fit_noise, ljung_box, ratchet
from aeromag_env.discovery.preparation import PreparedFlight
from aeromag_env.discovery.regressors import predict_all, width
from aeromag_env.discovery.whitened_problem import WhitenedProblem, ols
from aeromag_env.simulation.effects import EFFECTS, EffectContext, Group, SensorLag

#: Forward-selection steps at most.
MAX_EFFECTS = 5
#: A base residual below this std on every axis [nT] (1 pT, the finest magnetometers'
#: resolution) leaves nothing to find: no effect is tested.
RESOLUTION_NT = 1e-3
#: Alternations of the joint fit and the shifted modelled signal of a chosen sensor_lag.
LAG_SIGNAL_ITERATIONS = 3


def _renoise(prob: WhitenedProblem, chosen: list[int]) -> dict[str, Any]:
    """Re-fit the noise model after ``chosen[-1]`` entered and set it (through
    :func:`~aeromag_env.discovery.noise_model.ratchet`); returns what was done, for the report."""
    old = prob.noise
    assert old is not None
    b, _ = prob.fit(chosen)
    new = fit_noise(prob.residual(chosen, b), prob.gap)
    taus = np.array([old.fogm_tau_s, new.fogm_tau_s])
    share = prob.absorbable_share(chosen[:-1], chosen[-1], taus).max(axis=0)
    noise, kept = ratchet(old, new, share)
    prob.set_noise(noise)
    return {
        "absorbable_share": np.round(share, 6).tolist(),
        "coloured_part_kept": kept.tolist(),
        **noise.to_dict(),
    }


def lag_on_signal(
    prob: WhitenedProblem,
    groups: list[Group],
    chosen: list[int],
    base: np.ndarray,
    ctx: EffectContext,
    evidence: dict[int, dict[str, Any]],
) -> None:
    """Rebuild a chosen ``sensor_lag`` group as the modelled fluxgate signal shifted by its lag.

    Parameters
    ----------
    prob : WhitenedProblem
        The problem; the lag's columns are replaced in it.
    groups : list of Group
        All candidate groups; the lag's entry is replaced.
    chosen : list of int
        Problem indices of the model, base (0) first. Nothing is done without a ``sensor_lag``.
    base : numpy.ndarray
        The base regressors (n, 3, 21).
    ctx : EffectContext
        The flight's model field context.
    evidence : dict
        Evidence per problem index; the lag's entry records the lag model.

    Notes
    -----
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
    ground = prob.data.ground
    # off the ground, the base columns lose part of the aircraft field, whose shift matters
    signal_base = base if ground is None else base_columns(ctx.t_b, ctx.tdot_b)
    lag_effect = EFFECTS["sensor_lag"]
    assert g.profile is not None and isinstance(lag_effect, SensorLag)
    for _ in range(LAG_SIGNAL_ITERATIONS):
        beta, _ = prob.fit(chosen)
        cols = [signal_base if j == 0 else groups[j - 1].columns for j in chosen]
        signal = ctx.t_b + _modelled(cols, beta, chosen.index(lag))
        g = lag_effect.group(dataclasses.replace(ctx, signal=signal), g.profile)
        if ground is not None:
            g = ground.group(g)
        groups[lag - 1] = g
        prob.replace(lag, g.columns)
    if lag in evidence:
        evidence[lag]["lag_model"] = "modelled signal shifted (S(t − τ) − S(t))"


def _modelled(columns: list[Any], beta: np.ndarray, skip: int) -> np.ndarray:
    """The modelled field (n, 3) of every group of ``columns`` but ``skip``; ``beta`` holds the
    coefficients of all of them, concatenated."""
    parts = np.split(beta, np.cumsum([width(c) for c in columns])[:-1])
    keep = [k for k in range(len(columns)) if k != skip]
    return predict_all([columns[k] for k in keep], np.concatenate([parts[k] for k in keep]))


def refine(
    prob: WhitenedProblem,
    groups: list[Group],
    fractions: list[float],
    chosen: list[int],
    best: int,
    stats: dict[str, float],
) -> tuple[int, dict[str, float]]:
    """Refine a profiled group's parameter between its grid neighbours (bounded Brent search on
    the explained sum of squares, in log scale); the refined group joins the problem.

    Parameters
    ----------
    prob : WhitenedProblem
        The problem; a refined group is added to it.
    groups, fractions : list
        All candidate groups and their identifiable fractions; a refined group is appended
        (with its grid neighbour's fraction).
    chosen : list of int
        Problem indices of the model so far, base (0) first.
    best : int
        Problem index of the profiled group about to enter.
    stats : dict
        Its :func:`~aeromag_env.discovery.evidence.group_statistics`.

    Returns
    -------
    tuple of (int, dict)
        The problem index and statistics of the group to enter: the refined one when it
        explains more than ``best``, else ``best`` and ``stats`` unchanged.
    """
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
    return idx, group_statistics(t, 1)


def backward(
    prob: WhitenedProblem, groups: list[Group], chosen: list[int], alpha: float
) -> tuple[list[int], list[int]]:
    """Drop named groups without evidence (:func:`~aeromag_env.discovery.evidence.significant`,
    Holm over the k named) given all the others, the lowest ΔBIC first, until every one left has
    it.

    Parameters
    ----------
    prob : WhitenedProblem
        The problem.
    groups : list of Group
        All candidate groups.
    chosen : list of int
        Problem indices of the model, base (0) first.
    alpha : float
        Family-wise level.

    Returns
    -------
    tuple of (list of int, list of int)
        The problem indices kept (base first) and those retracted, in the order dropped.
    """
    retracted: list[int] = []
    while len(chosen) > 1:
        k = len(chosen) - 1
        tests = {}
        for j in chosen[1:]:
            others = [c for c in chosen if c != j]
            t = prob.test(others, j)
            extra = int(groups[j - 1].profile is not None)
            stats = None if t is None else group_statistics(t, extra)
            if stats is not None:
                stats = retest(prob, others, {j: stats}, {j: bool(extra)})[j]
            tests[j] = stats
        weak = [j for j, t in tests.items() if t is None or not significant(t, alpha / k)]
        if not weak:
            break
        worst = max(weak, key=lambda j: (math.inf, 0.0) if tests[j] is None else strength(tests[j]))  # type: ignore[arg-type]
        chosen = [c for c in chosen if c != worst]
        retracted.append(worst)
    return chosen, retracted


def forward(
    prob: WhitenedProblem,
    groups: list[Group],
    fractions: list[float],
    base: np.ndarray,
    ctx: EffectContext,
    alpha: float,
    say: Callable[[str], None],
) -> tuple[list[int], list[dict[str, Any]], dict[int, dict[str, Any]]]:
    """Forward selection: add the best group with evidence by ΔBIC until none has evidence.

    Parameters
    ----------
    prob : WhitenedProblem
        The problem with the base model's noise model set; groups and the noise model change.
    groups, fractions : list
        All candidate groups and their identifiable fractions (refined groups are appended).
    base : numpy.ndarray
        The base regressors (n, 3, 21).
    ctx : EffectContext
        The flight's model field context.
    alpha : float
        Family-wise level (Holm over the families left at each step).
    say : callable
        Progress messages.

    Returns
    -------
    tuple
        The problem indices chosen (base first), the record of each step (tests, Holm
        threshold, re-fitted noise model) and the evidence of each chosen group.
    """
    chosen = [0]
    steps: list[dict[str, Any]] = []
    evidence: dict[int, dict[str, Any]] = {}
    remaining = list(range(1, len(prob)))
    while remaining and len(chosen) - 1 < MAX_EFFECTS:
        say(f"testing {len(remaining)} candidate groups")
        live = step_tests(prob, groups, chosen, remaining)
        m = len(live)
        passing = {j: t for j, t in live.items() if significant(t, alpha / m)}
        steps.append(
            {
                "step": len(steps) + 1,
                "tests": {groups[j - 1].family: rounded(t) for j, t in live.items()},
                "holm_threshold": alpha / max(m, 1),
            }
        )
        if not passing:
            break
        best = min(passing, key=lambda j: strength(passing[j]))
        stats = passing[best]
        if groups[best - 1].rebuild is not None:
            best, stats = refine(prob, groups, fractions, chosen, best, stats)
        evidence[best] = {**stats, "holm_threshold": alpha / m, "step": len(steps)}
        chosen.append(best)
        remaining = [j for j in remaining if groups[j - 1].family != groups[best - 1].family]
        lag_on_signal(prob, groups, chosen, base, ctx, evidence)
        steps[-1]["noise_model"] = _renoise(prob, chosen)
    return chosen, steps, evidence


@dataclass
class Selection:
    """The selected model and how it was selected.

    Attributes
    ----------
    chosen : list of int
        Problem indices of the model, base (0) first; index ``j > 0`` is ``groups[j − 1]``.
    retracted : list of int
        Problem indices the backward pass dropped.
    beta, cov : numpy.ndarray
        GLS coefficients of ``chosen`` (concatenated, base first) and their covariance.
    beta_base : numpy.ndarray
        GLS coefficients of the base model alone, under the base model's noise model.
    steps : list of dict
        Record of each forward step.
    evidence : dict
        Statistics of each group that entered, by problem index.
    noise_before, noise_after : NoiseModel
        Noise model of the base model's residual and of the selected model's.
    lb_before, lb_after : tuple of float
        Ljung–Box statistic and p-value of the whitened residual, before and after.
    beta_without : dict
        Per named group (problem index), the GLS coefficients of the model without it.
    """

    chosen: list[int]
    retracted: list[int]
    beta: np.ndarray
    cov: np.ndarray
    beta_base: np.ndarray
    steps: list[dict[str, Any]]
    evidence: dict[int, dict[str, Any]]
    noise_before: NoiseModel
    noise_after: NoiseModel
    lb_before: tuple[float, float]
    lb_after: tuple[float, float]
    beta_without: dict[int, np.ndarray]


def select_effects(
    data: PreparedFlight,
    base: np.ndarray,
    groups: list[Group],
    fractions: list[float],
    alpha: float,
    say: Callable[[str], None],
) -> Selection:
    """Noise model, forward and backward selection, and the final fit on the calibration rows.

    Parameters
    ----------
    data : PreparedFlight
        The prepared flight.
    base : numpy.ndarray
        The base regressors (n, 3, 21).
    groups, fractions : list
        Candidate groups to test and their identifiable fractions; refined groups are appended
        and a chosen ``sensor_lag`` is rebuilt in place.
    alpha : float
        Family-wise level of the tests.
    say : callable
        Progress messages.

    Returns
    -------
    Selection
        The selected model, its fit, the noise models and the record of the selection.
    """
    ctx = data.ctx
    prob = WhitenedProblem(data, [base] + [g.columns for g in groups])
    beta0 = ols(prob, [0])
    noise_before = fit_noise(prob.residual([0], beta0), prob.gap)
    prob.set_noise(noise_before)
    lb_before = ljung_box(prob.whitened_residual([0]))
    beta_base, _ = prob.fit([0])
    floor = float(np.max(np.std(prob.residual([0], beta0), axis=0)))
    if floor < RESOLUTION_NT:  # a noise-free simulation: tests on rounding errors mean nothing
        chosen, evidence = [0], dict[int, dict[str, Any]]()
        steps: list[dict[str, Any]] = [
            {"step": 1, "tests": {}, "residual_std_nt": floor, "below_resolution_nt": RESOLUTION_NT}
        ]
    else:
        chosen, steps, evidence = forward(prob, groups, fractions, base, ctx, alpha, say)
    chosen, retracted = backward(prob, groups, chosen, alpha)
    chosen, vetoed = held_out_veto(
        prob, data, [base] + [g.columns for g in groups], chosen, evidence
    )
    retracted += vetoed
    lag_on_signal(prob, groups, chosen, base, ctx, evidence)
    beta, cov = prob.fit(chosen)
    lb_after = ljung_box(prob.whitened_residual(chosen))
    noise_after = (
        fit_noise(prob.residual(chosen, beta), prob.gap) if len(chosen) > 1 else noise_before
    )
    without = {j: prob.fit([c for c in chosen if c != j])[0] for j in chosen[1:]}
    return Selection(
        chosen,
        retracted,
        beta,
        cov,
        beta_base,
        steps,
        evidence,
        noise_before,
        noise_after,
        lb_before,
        lb_after,
        without,
    )
