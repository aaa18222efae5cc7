"""What the tuning environment accepts, named once: the ranges of the fields of
:class:`~aeromag_env.environment.config.EnvConfig` and its action and reward specs, and the keys
of ``reset``'s options.

Every refusal is a one-line :class:`~aeromag_env.errors.ConfigError` naming the field, the
allowed range and its unit, given when the configuration is made or ``reset`` is called, so
no value reaches the compiled step that could make a reward, an observation or an info value
NaN or infinite. The ranges are wide (they bound what floating point can carry through the
filter, not what is sensible); each says why it is where it is.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from aeromag_env.configs import check
from aeromag_env.environment.layout import RewardForm
from aeromag_env.environment.scenarios import SCENARIOS, TRAINING_SCENARIOS, check_scenario
from aeromag_env.errors import ConfigError

#: Largest decision window [samples] (a day of flight at 10 Hz is 864 000).
MAX_DECISION_WINDOW = 10**6
#: Range of ``reward.scale_nt`` [nT]: beyond it the squared reward of a large window error
#: (the state is bounded by the divergence check, the error to about 1e15 nT) could overflow.
REWARD_SCALE_RANGE_NT = (1e-3, 1e6)
#: Largest ``|divergence_penalty|`` (a reward): summed over episodes and normalised
#: (VecNormalize squares rewards), larger ones overflow.
MAX_PENALTY = 1e6
#: Range of ``duration_s`` [s]: at least ten samples at the presets' 10 Hz; at most a day
#: (the flight and the filter's arrays are held in memory).
DURATION_RANGE_S = (1.0, 86_400.0)
#: Largest cumulative scale of Q or R, ``scale_limit`` and 10^``MAX_DECADES`` (a factor): the
#: filter's products of Q and R (tr Q, K C_r Kᵀ, P) stay within floating point at 10^±100 of
#: the initial Q and R; at 10^±300 tr Q underflows and QOQ becomes infinite.
MAX_SCALE = 1e100
#: Largest magnitude of the absolute mode's log10 ranges [decades].
MAX_DECADES = 100.0
#: The keys ``reset(options=...)`` of the single environment takes.
RESET_OPTIONS = ("scenario",)
#: How an action sets the scales (:class:`~aeromag_env.environment.config.ActionSpec`).
ACTION_MODES = ("relative", "absolute")
#: How the Q of the permanent-field block T_p is set: with the other 18 states (``joint``), by a
#: third action (``graded``), or by a third action that is a switch (``gate``).
PERMANENT_MODES = ("joint", "graded", "gate")
#: Reward forms (:class:`~aeromag_env.environment.config.RewardSpec`): the names of
#: :class:`~aeromag_env.environment.layout.RewardForm`, which codes them for the compiled step.
REWARD_FORMS = tuple(form.name.lower() for form in RewardForm)
#: The (lo, hi) log10 ranges of the absolute mode (fields of the ActionSpec).
LOG10_RANGES = ("q_log10", "r_log10", "qp_log10")


def check_action(spec: Any) -> None:
    """Check an :class:`~aeromag_env.environment.config.ActionSpec` (its ``__post_init__``)."""
    check(
        isinstance(spec.mode, str) and spec.mode in ACTION_MODES,
        f"action.mode: relative or absolute, got {_shown(spec.mode)}",
    )
    check(
        isinstance(spec.permanent, str) and spec.permanent in PERMANENT_MODES,
        f"action.permanent: one of {', '.join(PERMANENT_MODES)}, got {_shown(spec.permanent)}",
    )
    check(
        spec.permanent != "gate" or spec.mode == "absolute",
        "action.permanent='gate' needs action.mode='absolute'",
    )
    require_number(
        spec, "s_max", 1.0, math.inf, "(a factor per step)", low_open=True, label="action.s_max"
    )
    require_number(
        spec, "scale_limit", 1.0, MAX_SCALE, "(a factor)", low_open=True, label="action.scale_limit"
    )
    for name in LOG10_RANGES:
        lo_hi = getattr(spec, name)
        ok = isinstance(lo_hi, tuple | list) and len(lo_hi) == 2 and all(map(is_real, lo_hi))
        require(
            ok and -MAX_DECADES <= lo_hi[0] < lo_hi[1] <= MAX_DECADES,
            f"action.{name}",
            f"(lo, hi) with lo < hi, each in [{-MAX_DECADES:g}, {MAX_DECADES:g}] [decades]",
            lo_hi,
        )


def check_reward(spec: Any) -> None:
    """Check a :class:`~aeromag_env.environment.config.RewardSpec` (its ``__post_init__``)."""
    check(
        isinstance(spec.form, str) and spec.form in REWARD_FORMS,
        f"reward.form: one of {', '.join(REWARD_FORMS)}",
    )
    require_number(spec, "scale_nt", *REWARD_SCALE_RANGE_NT, "[nT]", label="reward.scale_nt")
    require_number(
        spec,
        "divergence_penalty",
        -MAX_PENALTY,
        0.0,
        "(a reward)",
        label="reward.divergence_penalty",
    )


def check_config(cfg: Any) -> None:
    """Check the fields of an :class:`~aeromag_env.environment.config.EnvConfig` (its
    ``__post_init__``) that are not in its action and reward specs."""
    known = ", ".join(SCENARIOS + TRAINING_SCENARIOS)
    check(
        isinstance(cfg.scenario, str),
        f"unknown scenario {cfg.scenario!r}; valid scenarios: {known}",
    )
    check_scenario(cfg.scenario)
    require_number(cfg, "decision_window", 1, MAX_DECISION_WINDOW, "[samples]", integer=True)
    if cfg.recent_samples is not None:
        require_number(cfg, "recent_samples", 1, MAX_DECISION_WINDOW, "[samples]", integer=True)
    require_number(cfg, "score_from", 0.0, 1.0, "(a fraction of the flight)", high_open=True)
    if cfg.duration_s is not None:
        require_number(cfg, "duration_s", *DURATION_RANGE_S, "[s]")


def is_real(value: object) -> bool:
    """A real number: a Python or numpy integer or float (a bool is not one)."""
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(
        value, bool | np.bool_
    )


def _finite(value: Any) -> bool:
    """``math.isfinite`` that takes integers too large for a float (they are not finite here)."""
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def require(ok: bool, name: str, allowed: str, value: object) -> None:
    """A ConfigError ``name must be allowed, got value`` unless ``ok``."""
    if not ok:
        raise ConfigError(f"{name} must be {allowed}, got {_shown(value)}")


def require_number(
    cfg: Any,
    name: str,
    lo: float,
    hi: float,
    unit: str,
    *,
    integer: bool = False,
    low_open: bool = False,
    high_open: bool = False,
    label: str | None = None,
) -> None:
    """Field ``name`` of ``cfg`` a real number (an integer with ``integer``) in [lo, hi], with
    open ends as asked (an infinite end is open: the value must be finite); the message names
    it ``label`` if given."""
    v = getattr(cfg, name)
    kind = "an integer" if integer else "a number"
    left, right = "(" if low_open else "[", ")" if high_open else "]"
    allowed = f"{kind} in {left}{lo:g}, {hi:g}{right} {unit}"
    if math.isinf(hi):
        allowed = f"a finite number {'>' if low_open else '≥'} {lo:g} {unit}"
    ok = is_real(v) and (isinstance(v, int | np.integer) or not integer) and _finite(v)
    ok = ok and (lo < v if low_open else lo <= v) and (v < hi if high_open else v <= hi)
    require(ok, label or name, allowed, v)


def reset_options(options: object, valid: tuple[str, ...]) -> dict[str, Any]:
    """``reset``'s ``options`` as a dict (None: empty), checked: a one-line ConfigError for
    something other than a mapping, a key not in ``valid`` or an unknown scenario."""
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        raise ConfigError(f"reset options must be a dict (or None), got {_shown(options)}")
    unknown = ", ".join(sorted(map(repr, set(options) - set(valid))))
    if unknown:
        raise ConfigError(f"unknown reset option(s) {unknown}; valid: {', '.join(valid)}")
    if "scenario" in options:
        check_scenario(options["scenario"])
    return dict(options)


def _shown(value: object) -> str:
    """``repr(value)`` on one line, at most 60 characters."""
    text = " ".join(repr(value).split())
    return text if len(text) <= 60 else text[:57] + "..."
