"""Effects library: extra physics beyond paper eq. 5, shared by the simulator and discovery.

Each effect has a canonical name (used verbatim in reports), a ``simulate`` that returns the
field it adds to the fluxgate signal (body axes, nT), and a ``groups`` that builds its candidate
regressor columns from the channels a flight has. The simulator injects what the discovery
workflow (:mod:`aeromag_env.discovery.workflow`) can name, and the workflow writes what it found
back as an
:class:`~aeromag_env.simulation.config.EffectConfig` whose ``simulate`` reproduces the fitted
columns, so a discovered model re-simulates exactly.

Effects the 21-state base model absorbs (a constant fluxgate offset into ``T_p``; scale,
non-orthogonality and misalignment into ``A``) are in the library too, marked ``absorbed_by``:
the simulator can inject them, and discovery shows they leave nothing to find.

This module is the registry (:data:`EFFECTS`, :func:`effect`, :func:`check_effect_config`,
:func:`simulate_effects`) and re-exports the library's public names. The protocol and shared
helpers are in :mod:`~aeromag_env.simulation.effects_base`; the effects are grouped by physics in
``effects_sensor`` (lag, fluxgate errors), ``effects_field`` (external variation, altitude
gradient), ``effects_onboard`` (currents, temperature drift) and ``effects_induced``
(second-order induced field, eddy decay).

Conventions: ``T`` body-frame Earth field, ``Ṫ``/``T̈`` its first/second time derivatives (central
differences, as the simulator's eddy field), ``C_nb`` body → NED; ``P_k`` Legendre polynomials
on the flight's time span mapped to [-1, 1] (parameter ``time_span_s``).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from aeromag_env.errors import ConfigError
from aeromag_env.simulation.effects_base import (
    DRIFT_DEGREES,
    EDDY_TAU_GRID_S,
    EXTERNAL_KNOT_SPACING_S,
    FIELD_SCALE_NT,
    LAG_GRID_S,
    Effect,
    EffectContext,
    Group,
    legendre,
    spline_basis,
    spline_knots,
)
from aeromag_env.simulation.effects_field import AltitudeGradient, ExternalFieldVariation
from aeromag_env.simulation.effects_induced import EddyTimeConstant, InducedSecondOrder
from aeromag_env.simulation.effects_onboard import OnboardCurrent, PermanentFieldDrift
from aeromag_env.simulation.effects_sensor import (
    FluxgateNonorthogonality,
    FluxgateOffset,
    FluxgateScale,
    Misalignment,
    SensorLag,
)

__all__ = [
    "ABSORBED",
    "DRIFT_DEGREES",
    "EDDY_TAU_GRID_S",
    "EFFECTS",
    "EXTERNAL_KNOT_SPACING_S",
    "FIELD_SCALE_NT",
    "IDENTIFIABLE",
    "LAG_GRID_S",
    "SIGNAL_EFFECTS",
    "AltitudeGradient",
    "EddyTimeConstant",
    "Effect",
    "EffectContext",
    "ExternalFieldVariation",
    "FluxgateNonorthogonality",
    "FluxgateOffset",
    "FluxgateScale",
    "Group",
    "InducedSecondOrder",
    "Misalignment",
    "OnboardCurrent",
    "PermanentFieldDrift",
    "SensorLag",
    "check_effect_config",
    "effect",
    "legendre",
    "simulate_effects",
    "spline_basis",
    "spline_knots",
]


#: Every effect by canonical name, identifiable ones first.
EFFECTS: dict[str, Effect] = {
    e.name: e
    for e in (
        OnboardCurrent(),
        ExternalFieldVariation(),
        PermanentFieldDrift(),
        InducedSecondOrder(),
        AltitudeGradient(),
        EddyTimeConstant(),
        SensorLag(),
        FluxgateOffset(),
        FluxgateScale(),
        FluxgateNonorthogonality(),
        Misalignment(),
    )
}
#: Effects the base model absorbs entirely (never reported as missing).
ABSORBED = tuple(nm for nm, e in EFFECTS.items() if e.absorbed_by)
#: Effects discovery can name.
IDENTIFIABLE = tuple(nm for nm, e in EFFECTS.items() if not e.absorbed_by)
#: Effects acting on the whole signal: applied after the additive ones, in this order.
SIGNAL_EFFECTS = ("fluxgate_scale", "fluxgate_nonorthogonality", "misalignment", "sensor_lag")


def effect(name: str) -> Effect:
    """The effect of that canonical name.

    Parameters
    ----------
    name : str
        Canonical name, a key of :data:`EFFECTS`.

    Returns
    -------
    Effect

    Raises
    ------
    ConfigError
        Unknown name (one line, listing the valid ones).
    """
    if name not in EFFECTS:
        raise ConfigError(f"unknown effect {name!r}; valid: {', '.join(EFFECTS)}")
    return EFFECTS[name]


def check_effect_config(cfg: Any) -> None:
    """Validate an :class:`~aeromag_env.simulation.config.EffectConfig`.

    Parameters
    ----------
    cfg : EffectConfig
        Its name, channel and parameters are checked.

    Raises
    ------
    ConfigError
        The first problem found, in one line.
    """
    effect(cfg.name).check(cfg.channel, cfg.parameters)


def simulate_effects(ctx: EffectContext, configs: tuple[Any, ...]) -> np.ndarray:
    """Sum of the configured effects' fields: additive effects first, then the signal effects
    (:data:`SIGNAL_EFFECTS`: sensor errors, lag) on the signal including them.

    Parameters
    ----------
    ctx : EffectContext
        The flight; ``ctx.signal`` (else ``ctx.t_b``) is the signal before the effects.
    configs : tuple of EffectConfig
        The effects to apply.

    Returns
    -------
    numpy.ndarray
        (n, 3) [nT], body axes.
    """
    base = ctx.signal if ctx.signal is not None else ctx.t_b
    additive = [c for c in configs if c.name not in SIGNAL_EFFECTS]
    signal_fx = sorted(
        (c for c in configs if c.name in SIGNAL_EFFECTS), key=lambda c: SIGNAL_EFFECTS.index(c.name)
    )
    total = np.zeros((ctx.n, 3))
    for c in additive:
        total += effect(c.name).simulate(ctx, c.channel, c.parameters)
    for c in signal_fx:
        ctx_sig = dataclasses.replace(ctx, signal=base + total)
        total += effect(c.name).simulate(ctx_sig, c.channel, c.parameters)
    return total
