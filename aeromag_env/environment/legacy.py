"""Read the environment settings of the first version's files: its flat keys, in today's terms.

The environment's first version spelled its settings as flat keys (``extras=True``,
``split_q=True``, ``action_mode="absolute"``, ``absolute_q_log10=…``, ``reward_form=…``…);
policy files and hyperparameter files written then still carry them (the trained policies'
metadata, ``training.json`` files, ``ppo.json`` before it named presets). Today's settings are
presets and specs only (:mod:`aeromag_env.environment.config`); this module is where the old
spelling is read, by the readers of stored files alone (:func:`upgrade`): the policy file reader
(:mod:`agents.policies.policy_file`) and the hyperparameter models
(:mod:`agents.training.hyperparameters`). ``gym.make``, :func:`~aeromag_env.environment.config.
env_config` and :class:`~aeromag_env.environment.config.EnvConfig` refuse the flat keys.

What each flat key becomes:

* ``action_mode``, ``s_max``, ``scale_limit``, ``absolute_q_log10``, ``absolute_r_log10``,
  ``absolute_qp_log10``: the :class:`~aeromag_env.environment.config.ActionSpec` fields
  ``mode``, ``s_max``, ``scale_limit``, ``q_log10``, ``r_log10``, ``qp_log10``
  (:data:`LEGACY_KEYS`);
* ``reward_form``, ``reward_scale_nt``, ``divergence_penalty``: the
  :class:`~aeromag_env.environment.config.RewardSpec` fields ``form``, ``scale_nt``,
  ``divergence_penalty``;
* ``split_q`` and ``qp_gate`` (switches): ``action.permanent`` ``graded`` and ``gate``;
* ``extras`` and the observation switches ``innovation_power``, ``step_statistic``,
  ``turn_rate``, ``innovation_bias``: the observation, rebuilt in the first version's column
  order (the paper's two, the five of :data:`EXTRAS`, ``log_qp_scale`` with ``split_q``, then
  each switch's columns, :data:`LEGACY_OBSERVATIONS`).

The first version had no presets: its settings start from the ``paper`` preset (its defaults).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Any

from aeromag_env.configs import from_dict, to_dict
from aeromag_env.environment.checks import require
from aeromag_env.environment.config import PRESETS, ActionSpec, RewardSpec
from aeromag_env.environment.observations import PAPER_OBSERVATIONS
from aeromag_env.errors import ConfigError

#: The five observations the first version's ``extras=True`` added.
EXTRAS = ("log_q_scale", "log_r_scale", "whiteness", "progress", "log_recent_ror")
#: The first version's observation switches (with ``extras``), in the order of their columns,
#: and the observations each added.
LEGACY_OBSERVATIONS = {
    "innovation_power": ("log_innovation_power", "log_mean_innovation_power"),
    "step_statistic": ("log_step_statistic",),
    "turn_rate": ("log_turn_rate",),
    "innovation_bias": ("log_innovation_bias",),
}
#: Flat keys of the first version and the spec field each sets.
LEGACY_KEYS = {
    "action_mode": ("action", "mode"),
    "s_max": ("action", "s_max"),
    "scale_limit": ("action", "scale_limit"),
    "absolute_q_log10": ("action", "q_log10"),
    "absolute_r_log10": ("action", "r_log10"),
    "absolute_qp_log10": ("action", "qp_log10"),
    "reward_form": ("reward", "form"),
    "reward_scale_nt": ("reward", "scale_nt"),
    "divergence_penalty": ("reward", "divergence_penalty"),
}
#: The first version's switches (true or false), translated as a group.
LEGACY_SWITCHES = ("extras", "split_q", "qp_gate", *LEGACY_OBSERVATIONS)
#: The keys of today's vocabulary that the first version did not have.
_NEW_KEYS = ("preset", "observations", "action", "reward")


def is_legacy(settings: Mapping[str, Any]) -> bool:
    """Whether the settings ``settings`` use a flat key of the first version."""
    return any(key in LEGACY_KEYS or key in LEGACY_SWITCHES for key in settings)


def upgrade(settings: Mapping[str, Any]) -> dict[str, Any]:
    """The environment settings ``settings`` of a stored file in today's vocabulary.

    Settings without a flat key are returned as they are (a copy). Flat keys are translated
    (the module's docstring says how); the result names the preset the settings are when they
    are one (``{"preset": "general"}``), else gives the observation and the full action and
    reward specs. The fields both versions share (``scenario``, ``decision_window``,
    ``duration_s``…) are kept as given.

    Raises
    ------
    ConfigError
        One line naming the flat key (``s_max (given as s_max)``), or a flat key mixed with
        today's keys (``preset``, ``observations``, ``action``, ``reward``).
    """
    out = dict(settings)
    if not is_legacy(out):
        return out
    mixed = [key for key in _NEW_KEYS if key in out]
    if mixed:
        flat = sorted(k for k in out if k in LEGACY_KEYS or k in LEGACY_SWITCHES)
        raise ConfigError(
            f"environment settings mix the first version's flat keys ({', '.join(flat)}) with "
            f"{', '.join(mixed)}; write presets and specs only"
        )
    paper = to_dict(PRESETS["paper"])
    specs = {"action": dict(paper["action"]), "reward": dict(paper["reward"])}
    switches: dict[str, bool] = {}
    given: dict[str, str] = {}
    for key in list(out):
        if key in LEGACY_KEYS:
            spec, name = LEGACY_KEYS[key]
            specs[spec][name] = out.pop(key)
            given[name] = key
        elif key in LEGACY_SWITCHES:
            value = out.pop(key)
            require(isinstance(value, bool), key, "true or false", value)
            switches[key] = value
    observations = _switched(specs["action"], switches)
    checked = {}
    for key, cls in (("action", ActionSpec), ("reward", RewardSpec)):
        try:
            checked[key] = to_dict(from_dict(cls, specs[key]))
        except ConfigError as e:
            raise ConfigError(_as_given(str(e), given)) from None
    return {**out, **_named(observations, checked["action"], checked["reward"])}


def _switched(action: dict[str, Any], switches: dict[str, bool]) -> tuple[str, ...]:
    """The observation the switches give (from the paper's two), and the T_p action they set
    in ``action`` (``split_q``: graded, ``qp_gate``: gate)."""
    flags = {"extras": False, "split_q": False, "qp_gate": False, **switches}
    for name in LEGACY_OBSERVATIONS:
        flags.setdefault(name, False)
    if flags["qp_gate"] and not (flags["split_q"] and action["mode"] == "absolute"):
        raise ConfigError("qp_gate needs split_q=True and action_mode='absolute'")
    if flags["split_q"]:
        action["permanent"] = "gate" if flags["qp_gate"] else "graded"
    for name in LEGACY_OBSERVATIONS:
        if flags[name] and not flags["extras"]:
            raise ConfigError(f"{name} needs extras=True")
    if not flags["extras"]:
        return PAPER_OBSERVATIONS
    chosen = [obs for key, obs in LEGACY_OBSERVATIONS.items() if flags[key]]
    qp = ("log_qp_scale",) if flags["split_q"] else ()
    return PAPER_OBSERVATIONS + EXTRAS + qp + sum(chosen, ())


def _named(
    observations: tuple[str, ...], action: dict[str, Any], reward: dict[str, Any]
) -> dict[str, Any]:
    """The preset these settings are (``{"preset": name}``), or the settings themselves."""
    for name, config in PRESETS.items():
        if (config.observations, to_dict(config.action), to_dict(config.reward)) == (
            observations,
            action,
            reward,
        ):
            return {"preset": name}
    return {"observations": list(observations), "action": action, "reward": reward}


def _as_given(message: str, given: dict[str, str]) -> str:
    """``message`` about a spec's field, naming the flat key the file gave it under."""
    for name, key in given.items():
        if re.search(rf"\b{name}\b", message) and key not in message:
            message += f" (given as {key})"
    return message
