"""Named environment configurations: the presets that ids, policy files and users refer to.

``paper`` is the paper's setting (its two observations, relative actions ``s = 2 ** a``, the
log reward): the default of every registered id (:mod:`aeromag_env.environment.ids`).
``nonstationary`` and ``general`` are the settings the shipped PPO policies were trained with
(``agents/trained/ppo_nonstationary.npz``, ``ppo_general.npz``, whose metadata names them).
A preset's scenario is ``nominal``; the id or a keyword chooses the scenario.

``gym.make("AeroMag/Nonstationary-v0", preset="nonstationary")``, or in a dict
``{"preset": "general", "decision_window": 5}``.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

from aeromag_env.environment.config import EXTRAS, ActionSpec, EnvConfig
from aeromag_env.environment.observations import PAPER_OBSERVATIONS
from aeromag_env.errors import ConfigError

#: The observations both shipped policies read: the paper's two, the five of the first
#: version's ``extras``, the T_p Q scale and the two innovation powers.
_DETECTOR_OBSERVATIONS = (
    *PAPER_OBSERVATIONS,
    *EXTRAS,
    "log_qp_scale",
    "log_innovation_power",
    "log_mean_innovation_power",
)

#: The registry of presets (read-only).
PRESETS: Mapping[str, EnvConfig] = MappingProxyType(
    {
        "paper": EnvConfig(),
        "nonstationary": EnvConfig(
            observations=_DETECTOR_OBSERVATIONS,
            action=ActionSpec(
                mode="absolute",
                scale_limit=1e10,
                q_log10=(-4.0, 4.0),
                r_log10=(-1.0, 3.0),
                qp_log10=(-2.0, 10.0),
                permanent="gate",
            ),
        ),
        "general": EnvConfig(
            observations=(
                *_DETECTOR_OBSERVATIONS,
                "log_step_statistic",
                "log_turn_rate",
                "log_innovation_bias",
            ),
            action=ActionSpec(
                mode="absolute",
                scale_limit=1e10,
                q_log10=(-10.0, 2.0),
                r_log10=(-2.0, 7.0),
                qp_log10=(-6.0, 10.0),
                permanent="graded",
            ),
        ),
    }
)


def preset(name: object) -> EnvConfig:
    """The preset ``name``; a one-line ConfigError naming the presets for another name."""
    if not isinstance(name, str) or name not in PRESETS:
        raise ConfigError(f"unknown preset {name!r}; valid presets: {', '.join(PRESETS)}")
    return PRESETS[name]
