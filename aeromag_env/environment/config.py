"""The tuning environment's settings as data: the observation, the action mapping, the reward.

:class:`EnvConfig` composes three choices: the observation (a tuple of names from the registry
:mod:`aeromag_env.environment.observations`), the action mapping (:class:`ActionSpec`) and the
reward (:class:`RewardSpec`), beside the episode's scenario and timing. Named configurations are
presets (:data:`PRESETS`); :func:`env_config` builds a configuration from
a preset name, a config or a dict, and keyword changes, as ``gym.make`` passes them.

Dicts may be partial (``{"preset": "general", "decision_window": 5}``, ``{"action": {"s_max":
3.0}}``). The flat keys of the environment's first version (``extras=True``, ``split_q=True``,
``action_mode="absolute"``…) are refused here: the readers of the files written then translate
them (:mod:`aeromag_env.environment.legacy`). Every refusal is a one-line
:class:`~aeromag_env.errors.ConfigError`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from aeromag_env.configs import from_dict, to_dict
from aeromag_env.environment.checks import check_action, check_config, check_reward, require
from aeromag_env.environment.observations import PAPER_OBSERVATIONS, check_observations
from aeromag_env.errors import ConfigError


@dataclass(frozen=True, kw_only=True)
class ActionSpec:
    """How an action ``a`` in [-1, 1] sets the scales of Q and R (the paper's eq. 21).

    Attributes
    ----------
    mode : ``relative`` (each action multiplies Q and R by ``s_max ** a``, the paper's) or
        ``absolute`` (the action sets the scale: ``log10(Q / Q(0)) = lo + (a + 1)/2 · (hi −
        lo)`` within ``q_log10``, likewise R within ``r_log10``; a constant tuning is a
        constant action)
    s_max : largest scale factor per step in the relative mode (finite, > 1)
    scale_limit : the cumulative scales stay within [1/limit, limit] of Q(0) and R(0), limit
        in (1, 1e100]
    q_log10, r_log10, qp_log10 : (lo, hi) ranges of the absolute mode for Q, R and the Q of the
        permanent-field block T_p, lo < hi, each in [-100, 100] [decades]
    permanent : the Q of T_p (3 states): ``joint`` (scaled with the rest by ``a_q``; two
        actions), ``graded`` (a third action ``a_qp`` scales it, mapped like ``a_q``, which then
        scales the induced and eddy blocks only: an interference step moves T_p, and raising
        the whole Q to follow it unsettles the 18 coefficients) or ``gate`` (the third action
        is a switch, absolute mode only: ``a_qp > 0`` sets T_p's Q to the top of ``qp_log10``,
        otherwise to the bottom)
    """

    mode: str = "relative"
    s_max: float = 2.0
    scale_limit: float = 1e8
    q_log10: tuple[float, ...] = (-10.0, 10.0)
    r_log10: tuple[float, ...] = (-3.0, 3.0)
    qp_log10: tuple[float, ...] = (-10.0, 10.0)
    permanent: str = "joint"

    def __post_init__(self) -> None:
        check_action(self)

    @property
    def size(self) -> int:
        """Entries of one action: 2, or 3 with a T_p action."""
        return 2 if self.permanent == "joint" else 3


@dataclass(frozen=True, kw_only=True)
class RewardSpec:
    """The reward of a decision window from the true error ``e_w`` (RMS over the window of the
    true interference minus the filter's a-priori estimate, pooled over axes) [nT].

    Attributes
    ----------
    form : ``log`` (``−ln(1 + e_w/scale)``), ``linear`` (``−e_w/scale``) or ``squared``
        (``−(e_w/scale)²``: the sum over a flight is its mean squared error, where ``log``
        discounts the large errors after an interference step)
    scale_nt : the error scale, in [1e-3, 1e6] [nT]
    divergence_penalty : the reward of the step on which the filter diverges, in [-1e6, 0]
    """

    form: str = "log"
    scale_nt: float = 1.0
    divergence_penalty: float = -10.0

    def __post_init__(self) -> None:
        check_reward(self)


@dataclass(frozen=True, kw_only=True)
class EnvConfig:
    """Environment settings (a tuner's hyperparameters live elsewhere); the defaults are the
    ``paper`` preset.

    Attributes
    ----------
    scenario : one of :data:`aeromag_env.environment.scenarios.SCENARIOS` (or a training one)
    decision_window : K, samples the filter advances per step, an integer in [1, 10^6]
    recent_samples : samples of the "last decision window" statistics (the recent ROR, the mean
        innovation power and the two-window change statistic), an integer in [1, 10^6]; None:
        K
    score_from : fraction of the flight after which ``episode_rmse_nt`` is accumulated, in
        [0, 1)
    duration_s : override of the scenario's flight length, in [1, 86 400] [s] (None: the
        scenario's)
    observations : the observation's columns, names of
        :data:`aeromag_env.environment.observations.REGISTRY`, each once
    action : the action mapping
    reward : the reward
    """

    scenario: str = "nominal"
    decision_window: int = 10
    recent_samples: int | None = None
    score_from: float = 0.5
    duration_s: float | None = None
    observations: tuple[str, ...] = PAPER_OBSERVATIONS
    action: ActionSpec = field(default_factory=ActionSpec)
    reward: RewardSpec = field(default_factory=RewardSpec)

    def __post_init__(self) -> None:
        check_config(self)
        for name, spec in (("action", ActionSpec), ("reward", RewardSpec)):
            value = getattr(self, name)
            require(isinstance(value, spec), name, f"an {spec.__name__}", value)
        if isinstance(self.observations, list):  # a JSON list
            object.__setattr__(self, "observations", tuple(self.observations))
        check_observations(self.observations, self.action.permanent != "joint")

    @staticmethod
    def canonical_dict(data: Mapping[str, Any]) -> dict[str, Any]:
        """``data`` (a preset name under ``"preset"``, fields, partial specs) as the full dict
        of an EnvConfig; :func:`aeromag_env.configs.from_dict` reads
        an EnvConfig's dicts through it."""
        data = dict(data)
        return _changed(_preset_dict(data.pop("preset", None)), data)


_FIELDS = tuple(f.name for f in dataclasses.fields(EnvConfig))

# The presets: ``paper`` is the paper's setting (its two observations, relative actions
# ``s = 2 ** a``, the log reward), the default of every registered id
# (:mod:`aeromag_env.environment.ids`); ``nonstationary`` and ``general`` are the settings the
# shipped PPO policies were trained with (``agents/policies/trained/ppo_nonstationary.npz``,
# ``ppo_general.npz``, whose metadata names them). A preset's scenario is ``nominal``; the id or a
# keyword chooses the scenario.
#: The observations both shipped policies read: the paper's two, the current Q and R scales,
#: the innovation whiteness, the flight's progress, the recent ROR, the T_p Q scale and the two
#: innovation powers.
_DETECTOR_OBSERVATIONS = (
    *PAPER_OBSERVATIONS,
    "log_q_scale",
    "log_r_scale",
    "whiteness",
    "progress",
    "log_recent_ror",
    "log_qp_scale",
    "log_innovation_power",
    "log_mean_innovation_power",
)

#: The registry of presets (read-only): ``gym.make(id, preset=name)``, or in a dict
#: ``{"preset": "general", "decision_window": 5}``.
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


def env_config(config: EnvConfig | Mapping[str, Any] | None = None, **changes: Any) -> EnvConfig:
    """The configuration ``config`` with ``changes``, checked.

    Parameters
    ----------
    config : an EnvConfig, a dict (partial; may name a ``"preset"``) or None (the preset named
        by ``changes["preset"]``, or ``paper``)
    changes : fields of EnvConfig, partial ``action`` / ``reward`` dicts, or ``preset`` (the
        base when ``config`` is not a complete EnvConfig)

    Raises
    ------
    ConfigError
        One line naming the field (or the unknown key or preset) and what it may be.
    """
    preset = changes.pop("preset", None)
    if isinstance(config, EnvConfig):
        base = to_dict(config)
    elif config is None or isinstance(config, Mapping):
        data = dict(config or {})
        base = _changed(_preset_dict(data.pop("preset", preset)), data)
    else:
        raise ConfigError(
            f"config must be an EnvConfig, a dict or None, got {type(config).__name__}"
        )
    return from_dict(EnvConfig, {"preset": None, **_changed(base, changes)})


def _preset_dict(name: object) -> dict[str, Any]:
    return to_dict(preset("paper" if name is None else name))


def _changed(base: dict[str, Any], changes: Mapping[str, Any]) -> dict[str, Any]:
    """``base`` (a full EnvConfig dict) with ``changes`` (fields, partial specs) applied."""
    out = {
        **base,
        "action": dict(_spec_dict(base["action"])),
        "reward": dict(_spec_dict(base["reward"])),
    }
    for key, value in changes.items():
        if key in ("action", "reward"):
            value = _spec_dict(value)
            if not isinstance(value, Mapping):
                raise ConfigError(
                    f"{key} must be an {key.capitalize()}Spec or a dict, got {value!r}"
                )
            out[key].update(value)
        elif key in _FIELDS:
            out[key] = value
        else:
            raise ConfigError(_unknown(key))
    for key, cls in (("action", ActionSpec), ("reward", RewardSpec)):
        out[key] = from_dict(cls, out[key])
    return out


def _unknown(key: str) -> str:
    """The error for ``key``, no field of EnvConfig; it says where the flat keys of the
    environment's first version (``extras``, ``split_q``…) are read: from old files only."""
    valid = ", ".join((*_FIELDS, "preset"))
    return (
        f"EnvConfig: unknown field {key!r}; valid: {valid} (the first version's flat keys are "
        "read from old files only, by aeromag_env.environment.legacy.upgrade)"
    )


def _spec_dict(value: Any) -> Any:
    """A spec as its dict (anything else unchanged)."""
    return to_dict(value) if isinstance(value, ActionSpec | RewardSpec) else value
