"""The discovery report: named effects, every candidate's verdict, the selection record, data.

Decides what ``report.json`` says: each named effect with its channel, evidence (and its field's
RMS on the held-out part), fitted parameters, standard errors and physical reading; the verdict
on every candidate family (added, retracted, not significant, absorbed); how the selection was
made, step by step; the base model's coefficients before and after; and how the flight's samples
were used.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from aeromag_env.discovery.base_model import BaseSpan, base_dict, base_state
from aeromag_env.discovery.candidates import Candidates
from aeromag_env.discovery.evidence import JOINT_PENALTY, MIN_DELTA_BIC, rounded
from aeromag_env.discovery.gap import effect_gap, rms
from aeromag_env.discovery.ground import SEPARABLE_FRACTION, as_fitted
from aeromag_env.discovery.joint import SCREEN_P
from aeromag_env.discovery.preparation import PreparedFlight
from aeromag_env.discovery.regressors import predict
from aeromag_env.discovery.selection import Selection
from aeromag_env.flight.data import Flight
from aeromag_env.simulation.effects import Group


def build_report(
    flight: Flight,
    flux: str,
    alpha: float,
    data: PreparedFlight,
    cands: Candidates,
    sel: Selection,
    missing: list[dict[str, Any]],
    gap: dict[str, Any],
    diagnostics: dict[str, Any],
) -> dict[str, Any]:
    """The JSON-ready report of :func:`~aeromag_env.discovery.workflow.discover`.

    Parameters
    ----------
    flight, flux, alpha
        The flight, its vector magnetometer and the family-wise level of the tests.
    data : PreparedFlight
        The prepared flight.
    cands : Candidates
        The candidate groups (as left by the selection), skipped effects and absorbed groups.
    sel : Selection
        The selected model.
    missing, gap, diagnostics
        The named effects (:func:`missing_effects`), the held-out gap
        (:func:`~aeromag_env.discovery.gap.gap_record`) and the diagnostics
        (:func:`~aeromag_env.discovery.diagnostics.diagnostics`).

    Returns
    -------
    dict
        ``missing_effects``, ``gap``, ``verdict``, ``caveats``, ``ground``, ``candidates``,
        ``skipped``, ``selection``, ``diagnostics``, ``base_model`` and ``data``.
    """
    groups = cands.groups
    return {
        "missing_effects": [
            {k: e[k] for k in ("name", "channel", "evidence", "held_out_gap", "parameters")}
            | {"standard_errors": e["standard_errors"], "physical": e["physical"]}
            for e in missing
        ],
        "gap": gap,
        "verdict": (
            "nothing significant is missing"
            if not missing
            else "missing: " + ", ".join(groups[j - 1].family for j in sel.chosen[1:])
        )
        + ("" if data.ground is None else " off the ground"),
        "caveats": caveats(sel, gap, data.ground is not None, _unjudged(cands, sel)),
        "ground": _ground_record(data, cands),
        "candidates": candidate_verdicts(cands, sel),
        "skipped": cands.skipped,
        "selection": _selection_record(alpha, groups, sel),
        "diagnostics": diagnostics,
        "base_model": {
            "coefficients": base_dict(base_state(as_fitted(sel.beta_base, data.ground))),
            "augmented_coefficients": base_dict(base_state(as_fitted(sel.beta, data.ground))),
        },
        "data": _data_record(flight, flux, data),
    }


#: A slow signal no candidate explains, above this size [nT], is a caveat: the coloured part of
#: the final noise model (std, on any axis) or the held-out gap with the named effects. Of the
#: 716 suite flights it flagged one, a pair whose temperature drift went unnamed; over
#: simulated crustal geology (``GeologyConfig``) of 10 nT at 400 m the held-out gap was
#: 5.6–7.8 nT, of 50 nT 27–38 nT (``python -m experiments.discovery_geology``).
SLOW_RESIDUAL_NT = 5.0


def caveats(
    sel: Selection,
    gap: dict[str, Any],
    ground: bool = False,
    inseparable: list[dict[str, Any]] | None = None,
) -> list[str]:
    """One-line cautions on what the verdict can say: a large slow signal no candidate explains
    (:data:`SLOW_RESIDUAL_NT`), which on survey lines is mostly crustal geology, and, with
    ground separation, the effects not named that the ground's span leaves too little of to
    judge (``inseparable``).

    With 50 nT of simulated geology and no ground separation, effects at SNR 2 that vary slowly
    or with the attitude (``external_field_variation``, ``permanent_field_drift``,
    ``induced_second_order``, ``altitude_gradient``) were all missed, while ``onboard_current``,
    ``eddy_time_constant`` and ``sensor_lag`` were found; one of six plain flights named two
    decoys.
    """
    out = []
    if inseparable:
        names = ", ".join(
            dict.fromkeys(
                d["name"] + (f" ({d['channel']})" if d["channel"] else "") for d in inseparable
            )
        )
        out.append(
            f"the ground reference absorbs, or leaves under {SEPARABLE_FRACTION:.0%} of, {names}: "
            "on this flight they can hardly be told from geology, so their verdicts say little "
            "of them"
        )
    noise = sel.noise_after
    i = int(np.argmax(noise.fogm_std_nt))
    fogm, tau, white = noise.fogm_std_nt[i], noise.fogm_tau_s[i], noise.white_std_nt[i]
    held_out = float(gap.get("rms_after_nt") or 0.0)
    if max(fogm, held_out) <= SLOW_RESIDUAL_NT:
        return out
    what = (
        f"held-out gap {held_out:.1f} nT; the noise model's slow part {fogm:.1f} nT RMS, "
        f"correlation time {tau:.0f} s, on axis {'xyz'[i]}; white floor {white:.2f} nT"
    )
    if ground:
        return [
            *out,
            f"even off the ground's span the residual holds a signal no candidate "
            f"explains ({what}): geology shorter than the knots (flown lower than the "
            "clearance says?) or an effect outside the library",
        ]
    return [
        *out,
        f"the residual holds a slow signal no candidate explains ({what}): on survey lines that "
        "is mostly crustal geology. Slow or attitude-driven effects smaller than it "
        "(external_field_variation, permanent_field_drift, induced_second_order, "
        "altitude_gradient) cannot be told from it and may be missed or misnamed, and the "
        "held-out gap measures it; separate the ground (--ground separate) or fit on a "
        "calibration box flown high (--calibration-window)",
    ]


def _unjudged(cands: Candidates, sel: Selection) -> list[dict[str, Any]]:
    """The groups, not named, that the ground reference absorbs or leaves too little of."""
    named = {(cands.groups[j - 1].effect, cands.groups[j - 1].channel) for j in sel.chosen[1:]}
    out = [d for d in cands.inseparable if (d["name"], d["channel"]) not in named]
    return out + [a for a in cands.absorbed if "ground" in a["absorbed_by"]]


def _ground_record(data: PreparedFlight, cands: Candidates) -> dict[str, Any]:
    """The report's ``ground`` entry: ``mode`` ``ignore``, or the ground reference used and the
    effects it leaves too little of."""
    if data.ground is None:
        return {"mode": "ignore"}
    return data.ground.record() | {"inseparable": cands.inseparable}


def missing_effects(
    data: PreparedFlight, groups: list[Group], sel: Selection, base: np.ndarray
) -> list[dict[str, Any]]:
    """The named effects with their evidence, parameters, standard errors and physical reading.

    Parameters
    ----------
    data : PreparedFlight
        The prepared flight (the effect field's RMS is taken on its held-out part).
    groups : list of Group
        All candidate groups (as left by the selection).
    sel : Selection
        The selected model.
    base : numpy.ndarray
        The base regressors (n, 3, 21): an effect's held-out RMS is of its field outside their
        span.

    Returns
    -------
    list of dict
        Per named effect, in the order selected: ``name``, ``channel``, ``evidence``,
        ``held_out_gap`` (the model without it, re-fitted, and with it), ``parameters``,
        ``standard_errors`` and ``physical``.
    """
    missing = []
    offset = 21
    # the effect's size: its field outside the base span on the held-out rows (a slow field in
    # the navigation frame trades hundreds of nT with T_p and A; only the rest is the effect)
    held_out = BaseSpan(base, data.held_out)
    for j in sel.chosen[1:]:
        g = groups[j - 1]
        p = g.columns.shape[2]
        b, se = sel.beta[offset : offset + p], np.sqrt(np.diag(sel.cov)[offset : offset + p])
        offset += p
        effect_field = predict(g.columns, b)
        missing.append(
            {
                "name": g.effect,
                "channel": g.channel,
                "evidence": {
                    **rounded(sel.evidence[j]),
                    "held_out_rms_nt": rms(held_out.perp(effect_field[:, :, None])),
                },
                "held_out_gap": effect_gap(data, base, groups, sel, j),
                "parameters": g.to_parameters(b),
                "standard_errors": dict(zip(g.labels, np.round(se, 12).tolist(), strict=True)),
                "physical": physical(g, b, se),
            }
        )
    return missing


def candidate_verdicts(cands: Candidates, sel: Selection) -> list[dict[str, Any]]:
    """Every candidate family's verdict (added, retracted, not significant), then the absorbed.

    Parameters
    ----------
    cands : Candidates
        The candidate groups (as left by the selection) and the absorbed groups.
    sel : Selection
        The selected model.

    Returns
    -------
    list of dict
        Per family (in the order of the groups): ``name``, ``channel``, ``regressors``,
        ``profiled_values``, ``identifiable_fraction``, ``verdict`` and ``last_test``; then
        each absorbed group with verdict ``absorbed``.
    """
    groups, fractions = cands.groups, cands.fractions
    chosen, retracted = sel.chosen, sel.retracted
    candidates = []
    last = sel.steps[-1]["tests"] if sel.steps else {}
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
    candidates += [{**a, "verdict": "absorbed"} for a in cands.absorbed]
    return candidates


def physical(g: Group, b: np.ndarray, se: np.ndarray) -> dict[str, Any]:
    """Parameters in physical units with 95 % intervals, where the effect has a natural one.

    Parameters
    ----------
    g : Group
        The named group.
    b, se : numpy.ndarray
        Its fitted coefficients and their standard errors.

    Returns
    -------
    dict
        The lag and gain for ``sensor_lag``; coefficients with unit, intervals and magnitude
        for channel- and altitude-following effects; otherwise the coefficients by label.
    """
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


def _selection_record(alpha: float, groups: list[Group], sel: Selection) -> dict[str, Any]:
    """How the effects were selected: level, correction, criterion, steps, retractions."""
    return {
        "alpha": alpha,
        "correction": "Holm over candidate groups at each step",
        "criterion": (
            "partial F-test on GLS-whitened residuals below the Holm threshold and "
            f"ΔBIC > {MIN_DELTA_BIC:g}; a slow group with p < {SCREEN_P:g} is re-tested with the "
            "noise model re-fitted jointly (evidence.test = 'joint noise model': χ² p-value of "
            f"the likelihood ratio below the Holm threshold, the ratio above {JOINT_PENALTY:g} "
            "per degree of freedom, "
            "and a better held-out prediction than without it); the strongest by p-value "
            "enters; backward: each named effect must meet the same rule given all the others"
        ),
        "sensor_lag_model": (
            "the whole modelled signal (Earth field, base aircraft field, other named "
            "additive effects) shifted by the lag, so the lag's shift of the aircraft eddy "
            "field is not left for eddy_time_constant"
        ),
        "steps": sel.steps,
        "retracted": [groups[j - 1].family for j in sel.retracted],
    }


def _data_record(flight: Flight, flux: str, data: PreparedFlight) -> dict[str, Any]:
    """How the flight's samples were used."""
    return {
        "samples": flight.n,
        "usable": int(data.usable.sum()),
        "calibration_samples": int(data.calibration.sum()),
        "held_out_samples": int(data.held_out.sum()),
        "held_out_scheme": data.scheme,
        "time_gaps": data.n_gaps,
        "nonfinite_samples_dropped": data.n_nonfinite,
        "flux": flux,
        "sample_interval_s": data.dt,
    }
