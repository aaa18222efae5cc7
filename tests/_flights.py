"""Simulated flights for tests, cached per session (simulating is fast, but not free)."""

from __future__ import annotations

import functools

from aeromag_env.flight.data import Flight
from aeromag_env.simulation.config import SimulationConfig, preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight


@functools.cache
def simulated(preset_name: str = "nominal", seed: int = 0, **overrides: object) -> Flight:
    """A simulated flight; keyword overrides use ``__`` for dots (``trajectory__pattern``)."""
    return simulate_flight(config_for(preset_name, **overrides), seed)


def config_for(preset_name: str = "nominal", **overrides: object) -> SimulationConfig:
    cfg = preset(preset_name)
    return (
        with_overrides(cfg, {k.replace("__", "."): v for k, v in overrides.items()})
        if overrides
        else cfg
    )
