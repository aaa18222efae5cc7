"""Evidence for a candidate group: the partial F-test, ΔBIC and Holm's correction.

Decides whether a group has evidence (:func:`significant`): its F-test on the whitened problem
passes Holm's correction (``p < α / m`` with m groups left) *and* its ΔBIC is positive. The
F-test alone keeps a fixed false-inclusion rate per flight (about α) and trusts the fitted noise
model, whose slow part a 20-min calibration under-states; the BIC penalty, ``log(rows)`` per
regressor, grows with the data and asks a 3-regressor group for F > 10 rather than F > 6.
Groups that differ only in a non-linear parameter (a family: the eddy time constant, the lag)
compete as one, their best member with one more degree of freedom (:func:`best_of_families`).
A slow group re-tested with the noise model fitted jointly (:mod:`~aeromag_env.discovery.joint`)
has evidence when its likelihood ratio passes Holm and exceeds :data:`JOINT_PENALTY` per degree
of freedom. Groups are ranked by p-value (:func:`strength`).
"""

from __future__ import annotations

import math

from aeromag_env.simulation.effects import Group

#: Family-wise false-alarm level of the effect tests (Holm-corrected over candidate groups).
ALPHA = 0.01
#: ``test`` of statistics from the joint noise-model fit (:mod:`~aeromag_env.discovery.joint`).
JOINT_TEST = "joint noise model"
#: A group named by the joint test needs its likelihood ratio above this per degree of freedom
#: (besides Holm): the χ² reference is asymptotic and was anti-conservative for slow groups (a
#: time polynomial or a slow decoy channel named on 3 of 60 null flights with Holm alone).
#: Calibrated on 46 development null flights (seeds 90000+, not the suite's;
#: ``experiments/discovery_calibration.py``): spurious slow groups passing Holm reached LR/dof
#: 4.1, 4.6, 4.9 and 8.5 (one flight); true effects at SNR 0.5–1 and the nominal preset's
#: external variation had 7.4–29. BIC's log(rows) (10.6) wrote off those, AIC's 2 names the
#: spurious ones.
JOINT_PENALTY = 6.0
#: A group needs ΔBIC above this (besides the Holm-corrected F-test) to enter or to stay.
MIN_DELTA_BIC = 0.0


def group_statistics(t: dict[str, float], extra_dof: int) -> dict[str, float]:
    """F-test, ΔBIC and explained share of one candidate (``extra_dof`` profiled parameters).

    Parameters
    ----------
    t : dict
        Residual sums of :meth:`~aeromag_env.discovery.whitened_problem.WhitenedProblem.test`.
    extra_dof : int
        Profiled non-linear parameters, counted as extra degrees of freedom.

    Returns
    -------
    dict
        ``f_statistic``, ``dof``, ``p_value``, ``log10_p_value`` (floored at −300),
        ``delta_bic`` and ``explained_fraction``.
    """
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


def significant(stats: dict[str, float], threshold: float) -> bool:
    """Evidence for a group: its F-test passes the (Holm) ``threshold`` and its ΔBIC exceeds
    :data:`MIN_DELTA_BIC`.

    Parameters
    ----------
    stats : dict
        The group's :func:`group_statistics` (``p_value`` and ``delta_bic`` are read).
    threshold : float
        The Holm-corrected level, ``α / m``.

    Returns
    -------
    bool
        Whether the group has evidence.

    Notes
    -----
    ``ΔBIC = ΔRSS/σ² − p log(rows) > 0`` is ``F > log(rows)`` (about 10.5 on a 20-min, 10-Hz
    calibration, three axes): a Bayes factor for the group (Schwarz's approximation). Its
    false-inclusion rate falls as the flight grows, where a fixed α would name a spurious group
    in about α of all flights — over hundreds of flights, decoy channels among them; and it
    leaves a margin for the fitted noise model, whose slow part a short calibration under-
    states (the whitened residual keeps slow power, and slow channels then look significant).
    """
    if stats.get("test") == JOINT_TEST:  # the noise model re-fitted with it (see JOINT_PENALTY)
        return stats["p_value"] < threshold and stats["lr_statistic"] > JOINT_PENALTY * stats["dof"]
    return stats["p_value"] < threshold and stats["delta_bic"] > MIN_DELTA_BIC


def strength(stats: dict[str, float]) -> tuple[float, float]:
    """Sort key of a group's evidence, strongest first: its log10 p-value (comparable across
    F- and likelihood-ratio tests and group sizes), then its ΔBIC (p-values below 1e-300 tie)."""
    return stats["log10_p_value"], -stats["delta_bic"]


def best_of_families(
    groups: list[Group], tests: dict[int, dict[str, float] | None]
) -> dict[int, dict[str, float]]:
    """One test per family (effect and channel): the best member by ΔRSS, with one more degree
    of freedom when the family profiles a non-linear parameter.

    Parameters
    ----------
    groups : list of Group
        All candidate groups (problem index ``j`` is ``groups[j − 1]``).
    tests : dict
        Residual sums per problem index (None: nothing identifiable).

    Returns
    -------
    dict
        :func:`group_statistics` of each family's best member, by its problem index.
    """
    best: dict[str, int] = {}
    size: dict[str, int] = {}
    for j, t in tests.items():
        if t is None:
            continue
        fam = groups[j - 1].family
        size[fam] = size.get(fam, 0) + 1
        if fam not in best or t["drss"] > tests[best[fam]]["drss"]:  # type: ignore[index]
            best[fam] = j
    return {j: group_statistics(tests[j], int(size[fam] > 1)) for fam, j in best.items()}  # type: ignore[arg-type]


def rounded(d: dict[str, float]) -> dict[str, float]:
    """Floats of ``d`` to 6 significant digits (for the report); other values as they are.

    Parameters
    ----------
    d : dict
        Statistics.

    Returns
    -------
    dict
        The same keys, floats rounded.
    """
    return {k: (float(f"{v:.6g}") if isinstance(v, float) else v) for k, v in d.items()}
