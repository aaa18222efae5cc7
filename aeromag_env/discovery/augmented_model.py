"""The augmented model as a simulator configuration: replay the flight to re-simulate it.

Decides how the discovered model reads as a simulator configuration
(:class:`~aeromag_env.simulation.config.SimulationConfig`): the fitted base coefficients as
fixed aircraft interference, the final noise model's medians over axes as the fluxgate noise,
the named effects with their fitted parameters, no scalar sensor and no Earth-field variation
(that is an effect here); the trajectory is the file's own when it carries a simulator
configuration.
"""

from __future__ import annotations

import contextlib
from typing import TYPE_CHECKING, Any

import numpy as np

from aeromag_env.discovery.noise_model import NoiseModel
from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import Flight
from aeromag_env.simulation.interference import STATE_SLICES

if TYPE_CHECKING:
    from aeromag_env.simulation.config import TrajectoryConfig


def model_config(
    flight: Flight, flux: str, state: np.ndarray, noise: NoiseModel | None, missing: list[dict]
) -> Any:
    """The augmented model as a simulator configuration (replay the flight to re-simulate it).

    Parameters
    ----------
    flight : Flight
        The flight (its stored simulator configuration, if any, gives the trajectory).
    flux : str
        The vector magnetometer.
    state : numpy.ndarray
        Base state ``[T_p, A row-major, B row-major]`` (21,).
    noise : NoiseModel
        The final noise model (must not be None).
    missing : list of dict
        The named effects (``name``, ``channel``, ``parameters``).

    Returns
    -------
    SimulationConfig
        The augmented model, preset ``"discovered"``.
    """
    from aeromag_env.simulation.config import (
        EarthConfig,
        EffectConfig,
        InterferenceConfig,
        ScalarConfig,
        SensorNoiseConfig,
        SimulationConfig,
    )

    traj = _trajectory(flight)
    assert noise is not None
    return SimulationConfig(
        preset="discovered",
        fluxgate=flux,
        trajectory=traj,
        earth=EarthConfig(daily_amplitude_nt=0.0, external_fogm_std_nt=0.0),
        interference=InterferenceConfig(
            permanent_std_nt=0.0,
            induced_std=0.0,
            eddy_std_s=0.0,
            permanent_nt=tuple(state[STATE_SLICES["permanent"]]),
            induced=tuple(state[STATE_SLICES["induced"]]),
            eddy_s=tuple(state[STATE_SLICES["eddy"]]),
        ),
        fluxgate_noise=SensorNoiseConfig(
            white_std_nt=float(np.median(noise.white_std_nt)),
            fogm_std_nt=float(np.median(noise.fogm_std_nt)),
            fogm_tau_s=float(np.median(noise.fogm_tau_s)),
        ),
        scalar=ScalarConfig(enabled=False),
        effects=tuple(
            EffectConfig(name=e["name"], channel=e["channel"], parameters=e["parameters"])
            for e in missing
        ),
    )


def _trajectory(flight: Flight) -> TrajectoryConfig:
    """The trajectory of the flight's stored simulator configuration, else the default one."""
    from aeromag_env.configs import from_json
    from aeromag_env.simulation.config import SimulationConfig, TrajectoryConfig

    traj = TrajectoryConfig()
    if "config" in flight.attrs:
        with contextlib.suppress(AeromagError):
            traj = from_json(SimulationConfig, flight.attrs["config"]).trajectory
    return traj
