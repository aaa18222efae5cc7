"""The scenarios' names and their Gymnasium ids, named once (light: no simulator, no kernels).

``import aeromag_env`` registers, through :func:`register_all`, the generic id
``AeroMagCompensation-v0`` (the scenario a keyword, ``nominal`` by default) and one id per
scenario in the ``AeroMag`` namespace: ``AeroMag/Nonstationary-v0`` is
``AeroMagCompensation-v0`` with ``scenario="nonstationary"``. Every id names its preset
(:data:`ID_PRESET`; :mod:`aeromag_env.environment.config`), which ``preset=`` or ``config=``
replaces. Each works with ``gym.make``
(``max_episode_steps`` and ``render_mode`` passed through), ``gym.make_vec`` (the batched vector
environment with ``vectorization_mode="vector_entry_point"``, or Gymnasium's ``sync``/``async``)
and :class:`aeromag_env.environment.sb3.AeroMagSB3VecEnv`.
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

#: Scenarios that are evaluated and tabled; what each one tests is in
#: :mod:`aeromag_env.environment.scenarios`.
SCENARIOS = (
    "paper",
    "nominal",
    "misspecified",
    "nonstationary",
    "calibration_then_survey",
    "noise_bursts",
    "degradation",
    "manoeuvre_heavy",
)
#: Evaluated as a control, not part of the suite: the well-tuned start has no headroom by design
#: (a tuner must not make it worse).
CONTROL_SCENARIOS = ("nominal",)
#: The suite: every evaluated scenario with headroom (the general policy trains on these; the
#: normalized scores aggregate over them).
SUITE = tuple(s for s in SCENARIOS if s not in CONTROL_SCENARIOS)
#: Scenarios for training only (not evaluated or tabled): ``nonstationary_dense`` and ``suite``
#: (each episode one scenario of SUITE).
TRAINING_SCENARIOS = ("nonstationary_dense", "suite")
#: The generic id (scenario as a keyword) and the namespace of the per-scenario ids.
ENV_ID = "AeroMagCompensation-v0"
NAMESPACE = "AeroMag"
VERSION = 0
#: The preset every registered id starts from: the paper's setting.
ID_PRESET = "paper"
_ENTRY_POINT = "aeromag_env.environment.env:AeroMagCompensationEnv"
_VECTOR_ENTRY_POINT = "aeromag_env.environment.vec_env:AeroMagCompensationVecEnv"


def env_id(scenario: str) -> str:
    """The registered id of ``scenario``: ``calibration_then_survey`` →
    ``AeroMag/CalibrationThenSurvey-v0``. KeyError for a name that is not a scenario."""
    if scenario not in SCENARIOS + TRAINING_SCENARIOS:
        valid = ", ".join(SCENARIOS + TRAINING_SCENARIOS)
        raise KeyError(f"unknown scenario {scenario!r}; valid: {valid}")
    name = "".join(part.capitalize() for part in scenario.split("_"))
    return f"{NAMESPACE}/{name}-v{VERSION}"


def registered_ids() -> dict[str, dict[str, str]]:
    """Every id :func:`register_all` registers and its keyword arguments (its preset, and its
    scenario for the per-scenario ids)."""
    per_scenario = {
        env_id(s): {"preset": ID_PRESET, "scenario": s} for s in SCENARIOS + TRAINING_SCENARIOS
    }
    return {ENV_ID: {"preset": ID_PRESET}, **per_scenario}


def register_all() -> None:
    """Register the generic id and one id per scenario (once; a second call does nothing)."""
    for id_, kwargs in registered_ids().items():
        if id_ not in registry:
            register(
                id=id_,
                entry_point=_ENTRY_POINT,
                vector_entry_point=_VECTOR_ENTRY_POINT,
                kwargs=kwargs,
            )
