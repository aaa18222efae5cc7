"""Aircraft aeromagnetic compensation: flight files, simulator, compensators, tuning environment.

The public API, one name per job (each resolved on first use, so ``import aeromag_env`` stays
light; see the README, "How the code is laid out")::

    import aeromag_env as am

    result = am.compensate("flight.xyz", method="tl", out="out")    # = aeromag compensate
    result.metrics, result.warnings, result.report                  # numbers, warnings, report
    found = am.discover("flight.h5").report["missing_effects"]      # = aeromag discover
    rows = am.fleet("flights/", "out", method="kf").rows            # = aeromag compensate DIR
    model = am.calibrate("cal.h5", method="tl", out="cal").model    # fit once on a box
    result = am.compensate("survey.h5", model="cal/model.json")     # apply to other flights
    model = am.load_model("cal/model.json"); model.apply(flight)    # the model object
    live = model.stream(); live.update({"tt": 0.0, ...})            # one sample at a time
    flight = am.read_flight("flight.h5", needs=("tt", "flux_a_x"))  # read a flight file
    am.write_flight(flight, "copy.h5")                              # write one (atomically)
    flight = am.simulate_flight(am.preset("nominal"), rng=7)        # simulate one
    comp = am.compensate_vector(flight, "fakf")                     # the paper's filter alone
    metrics = am.score(flight, comp)                                # RMSE, IR, FOM…
    env = gymnasium.make(am.ENV_ID, scenario="nonstationary")       # the tuning environment

The jobs (``compensate``, ``discover``, ``fleet``: :mod:`aeromag_env.jobs`) do everything the
command line does (channels, fluxgate mount, gaps and spikes, provenance, the output set) and
return typed results; their warnings are :class:`~aeromag_env.errors.AeromagWarning`, also
listed in the result. ``compensate_vector`` takes the fluxgate's axes for body axes unless given
a ``mount``, and warns when the data say otherwise.

Importing the package registers the Gymnasium environment ``AeroMagCompensation-v0`` (the
scenario a keyword) and one id per scenario (``AeroMag/Nonstationary-v0``…,
:mod:`aeromag_env.environment.ids`), each with its batched vector form
(``gym.make_vec(..., vectorization_mode="vector_entry_point")``); the environment modules
themselves are imported only by ``gym.make`` / ``gym.make_vec``.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from aeromag_env.environment.ids import ENV_ID, register_all
from aeromag_env.version import __version__

register_all()  # ENV_ID (the generic id) and AeroMag/<Scenario>-v0 per scenario

#: Public name → the module that defines it (imported on first access, PEP 562); these and
#: ENV_ID, __version__ are ``__all__`` (tests/test_layout.py).
_PUBLIC = {
    "Flight": "aeromag_env.flight.data",
    "read_flight": "aeromag_env.flight.files",
    "write_flight": "aeromag_env.flight.files",
    "SimulationConfig": "aeromag_env.simulation.config",
    "preset": "aeromag_env.simulation.config",
    "simulate_flight": "aeromag_env.simulation.simulate",
    "FilterConfig": "aeromag_env.compensation.model",
    "Compensation": "aeromag_env.compensation.compensate",
    "compensate_vector": "aeromag_env.compensation.compensate",
    "compensate_scalar": "aeromag_env.compensation.compensate",
    "score": "aeromag_env.compensation.compensate",
    "TollesLawson": "aeromag_env.compensation.tolles_lawson",
    "EnvConfig": "aeromag_env.environment.env",
    "AeroMagCompensationEnv": "aeromag_env.environment.env",
    "AeroMagCompensationVecEnv": "aeromag_env.environment.vec_env",
    "SCENARIOS": "aeromag_env.environment.ids",
    "Discovery": "aeromag_env.discovery.workflow",
    "compensate": "aeromag_env.jobs.compensate",
    "calibrate": "aeromag_env.jobs.calibrate",
    "CalibrationResult": "aeromag_env.jobs.calibrate",
    "CalibrationModel": "aeromag_env.compensation.calibration_model",
    "load_model": "aeromag_env.compensation.calibration_model",
    "CompensationResult": "aeromag_env.jobs.compensate",
    "discover": "aeromag_env.jobs.discover",
    "DiscoverResult": "aeromag_env.jobs.discover",
    "fleet": "aeromag_env.jobs.fleet",
    "FleetResult": "aeromag_env.jobs.fleet",
    "AeromagError": "aeromag_env.errors",
    "AeromagWarning": "aeromag_env.errors",
}

__all__ = [
    "ENV_ID",
    "SCENARIOS",
    "AeroMagCompensationEnv",
    "AeroMagCompensationVecEnv",
    "AeromagError",
    "AeromagWarning",
    "CalibrationModel",
    "CalibrationResult",
    "Compensation",
    "CompensationResult",
    "DiscoverResult",
    "Discovery",
    "EnvConfig",
    "FilterConfig",
    "FleetResult",
    "Flight",
    "SimulationConfig",
    "TollesLawson",
    "__version__",
    "calibrate",
    "compensate",
    "compensate_scalar",
    "compensate_vector",
    "discover",
    "fleet",
    "load_model",
    "preset",
    "read_flight",
    "score",
    "simulate_flight",
    "write_flight",
]

if TYPE_CHECKING:  # what the lazy names are, for type checkers and IDEs
    from aeromag_env.compensation.calibration_model import CalibrationModel, load_model
    from aeromag_env.compensation.compensate import (
        Compensation,
        compensate_scalar,
        compensate_vector,
        score,
    )
    from aeromag_env.compensation.model import FilterConfig
    from aeromag_env.compensation.tolles_lawson import TollesLawson
    from aeromag_env.discovery.workflow import Discovery
    from aeromag_env.environment.env import AeroMagCompensationEnv, EnvConfig
    from aeromag_env.environment.ids import SCENARIOS
    from aeromag_env.environment.vec_env import AeroMagCompensationVecEnv
    from aeromag_env.errors import AeromagError, AeromagWarning
    from aeromag_env.flight.data import Flight
    from aeromag_env.flight.files import read_flight, write_flight
    from aeromag_env.jobs.calibrate import CalibrationResult, calibrate
    from aeromag_env.jobs.compensate import CompensationResult, compensate
    from aeromag_env.jobs.discover import DiscoverResult, discover
    from aeromag_env.jobs.fleet import FleetResult, fleet
    from aeromag_env.simulation.config import SimulationConfig, preset
    from aeromag_env.simulation.simulate import simulate_flight


def __getattr__(name: str) -> Any:
    module = _PUBLIC.get(name)
    if module is None:
        raise AttributeError(f"module 'aeromag_env' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # resolved once
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
