"""The gap: how far the simulated fluxgate is from the measured one on held-out data.

Decides the score of the base and the augmented model: both predict the held-out part, and the
gap is the RMS of measured minus simulated there above the white-noise floor,
``sqrt(RMS² − σ_w²)`` with ``σ_w`` from the final noise model (the sensor's white noise is no
model gap; the raw RMS is reported too).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from aeromag_env.discovery.preparation import PreparedFlight
from aeromag_env.discovery.regressors import predict, predict_all
from aeromag_env.discovery.selection import Selection
from aeromag_env.simulation.effects import Group


def rms(x: np.ndarray) -> float:
    """Root mean square of all elements of ``x`` (NaN when empty).

    Parameters
    ----------
    x : numpy.ndarray
        Values.

    Returns
    -------
    float
        ``sqrt(mean(x²))``.
    """
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else float("nan")


def gap_record(
    data: PreparedFlight, before: np.ndarray, after: np.ndarray, white: float
) -> tuple[dict[str, Any], np.ndarray, np.ndarray]:
    """Held-out gap: RMS of measured − simulated above the white-noise floor (the sensor's white
    noise, estimated by the noise model, is no model gap); the raw RMS is reported too.

    Parameters
    ----------
    data : PreparedFlight
        The prepared flight (measured minus model Earth field, masks).
    before, after : numpy.ndarray
        Predictions (n, 3) of the base and the augmented model [nT].
    white : float
        White-noise floor [nT].

    Returns
    -------
    tuple of (dict, numpy.ndarray, numpy.ndarray)
        The report's ``gap`` entry, and the residuals (n, 3) before and after (NaN where the
        sample is not usable).
    """
    r0 = np.where(data.usable[:, None], data.y - before, 0.0)
    r1 = np.where(data.usable[:, None], data.y - after, 0.0)
    h = data.held_out
    raw0, raw1 = rms(r0[h]), rms(r1[h])
    before_nt = math.sqrt(max(raw0**2 - white**2, 0.0))
    after_nt = math.sqrt(max(raw1**2 - white**2, 0.0))
    gap = {
        "rms_before_nt": before_nt,
        "rms_after_nt": after_nt,
        "shrink": before_nt / after_nt if after_nt > 0 else float("inf") if before_nt else 1.0,
        "evaluated_on": "held_out",
        "held_out_scheme": data.scheme,
        "definition": "sqrt(RMS² − σ_white²) of measured − simulated on the held-out samples",
        "white_noise_floor_nt": white,
        "raw_rms_before_nt": raw0,
        "raw_rms_after_nt": raw1,
    }
    return (
        gap,
        np.where(data.usable[:, None], r0, np.nan),
        np.where(data.usable[:, None], r1, np.nan),
    )


def held_out_gap(
    data: PreparedFlight, base: np.ndarray, groups: list[Group], sel: Selection
) -> tuple[dict[str, Any], np.ndarray, np.ndarray]:
    """The gap of the base and of the selected model (:func:`gap_record` of their predictions).

    Parameters
    ----------
    data : PreparedFlight
        The prepared flight.
    base : numpy.ndarray
        The base regressors (n, 3, 21).
    groups : list of Group
        All candidate groups (as left by the selection).
    sel : Selection
        The selected model; the white-noise floor is the RMS over axes of its final noise
        model's white part.

    Returns
    -------
    tuple of (dict, numpy.ndarray, numpy.ndarray)
        As :func:`gap_record`.
    """
    pred_before = predict(base, sel.beta_base)
    return gap_record(data, pred_before, _predict(base, groups, sel.chosen, sel.beta), _white(sel))


def effect_gap(
    data: PreparedFlight, base: np.ndarray, groups: list[Group], sel: Selection, j: int
) -> dict[str, float]:
    """Held-out gap of the selected model without named group ``j`` (re-fitted without it) and
    with it: what that one effect is worth on data no fit saw [nT]."""
    others = [c for c in sel.chosen if c != j]
    without = _predict(base, groups, others, sel.beta_without[j])
    gap, _, _ = gap_record(data, without, _predict(base, groups, sel.chosen, sel.beta), _white(sel))
    return {
        "rms_without_nt": gap["rms_before_nt"],
        "rms_with_nt": gap["rms_after_nt"],
        "shrink": gap["shrink"],
    }


def _predict(
    base: np.ndarray, groups: list[Group], chosen: list[int], beta: np.ndarray
) -> np.ndarray:
    """The field (n, 3) [nT] of the model ``chosen`` (base first) with coefficients ``beta``."""
    full = [base] + [g.columns for g in groups]
    return predict_all([full[j] for j in chosen], beta)


def _white(sel: Selection) -> float:
    """The white-noise floor: RMS over axes of the final noise model's white part [nT]."""
    return float(np.sqrt(np.mean(sel.noise_after.white_std_nt**2)))
