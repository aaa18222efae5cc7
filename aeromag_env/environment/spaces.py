"""The action and observation layouts of the tuning environment, named once.

An action is ``[a_q, a_r]``, or with ``split_q`` ``[a_q, a_r, a_qp]`` (:data:`ACTIONS`). An
observation is the paper's two ratios, with ``extras`` five more, then the optional ones each
switch of :class:`aeromag_env.environment.env.EnvConfig` adds, in the order of
:data:`OBSERVATIONS`; :func:`observation_names` gives the layout of a configuration. The compiled
step (:mod:`aeromag_env.environment.kernels`) writes each observation at the position
:func:`observation_positions` gives it; policies find a column with :func:`observation_index`.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

#: The entries of an action, in order; ``a_qp`` only with ``split_q``.
ACTIONS = ("a_q", "a_r", "a_qp")
#: Their positions: Q scale (of every state, or with ``split_q`` of the A and B blocks), R scale,
#: Q scale of the permanent-field block T_p.
ACT_Q, ACT_R, ACT_QP = ACTIONS.index("a_q"), ACTIONS.index("a_r"), ACTIONS.index("a_qp")
#: The actions without ``split_q``.
BASE_ACTIONS = ACTIONS[:2]

#: Every observation the environment can give, in the order it gives them (see the environment's
#: docstring for their meaning): two always, five more with ``extras``, then the optional ones of
#: :data:`OPTIONAL_OBSERVATIONS`.
OBSERVATIONS = (
    "log_ror",  # log10 ROR over the statistics window
    "log_qoq",  # log10 QOQ
    "log_q_scale",  # log10 of the cumulative Q scale
    "log_r_scale",  # log10 of the cumulative R scale
    "whiteness",  # lag-1 autocorrelation of the innovations over the last window
    "progress",  # progress through the flight
    "log_recent_ror",  # log10 ROR over the last decision window
    "log_qp_scale",  # log10 of the cumulative T_p Q scale
    "log_innovation_power",  # log10 mean |r|² over the statistics window / tr R(0)
    "log_mean_innovation_power",  # log10 |mean r|² over the last decision window / tr R(0)
    "log_step_statistic",  # log10 of the two-window change statistic
    "log_turn_rate",  # log10 RMS |Ṫ|/|T| over the last decision window [rad/s]
    "log_innovation_bias",  # log10 M |mean r|² / tr C over the statistics window
)
#: Each observation's index in OBSERVATIONS: for the first two (always given) and the five of
#: ``extras`` also its column, for the optional ones the row of :func:`observation_positions`.
OBS_LOG_ROR = OBSERVATIONS.index("log_ror")
OBS_LOG_QOQ = OBSERVATIONS.index("log_qoq")
OBS_LOG_Q_SCALE = OBSERVATIONS.index("log_q_scale")
OBS_LOG_R_SCALE = OBSERVATIONS.index("log_r_scale")
OBS_WHITENESS = OBSERVATIONS.index("whiteness")
OBS_PROGRESS = OBSERVATIONS.index("progress")
OBS_LOG_RECENT_ROR = OBSERVATIONS.index("log_recent_ror")
OBS_LOG_QP_SCALE = OBSERVATIONS.index("log_qp_scale")
OBS_LOG_INNOVATION_POWER = OBSERVATIONS.index("log_innovation_power")
OBS_LOG_MEAN_INNOVATION_POWER = OBSERVATIONS.index("log_mean_innovation_power")
OBS_LOG_STEP_STATISTIC = OBSERVATIONS.index("log_step_statistic")
OBS_LOG_TURN_RATE = OBSERVATIONS.index("log_turn_rate")
OBS_LOG_INNOVATION_BIAS = OBSERVATIONS.index("log_innovation_bias")
BASE_OBSERVATIONS = OBSERVATIONS[: OBS_LOG_QOQ + 1]
EXTRA_OBSERVATIONS = OBSERVATIONS[OBS_LOG_QOQ + 1 : OBS_LOG_RECENT_ROR + 1]
#: The switch that adds each optional observation (with ``extras``; they follow the extras in the
#: order of OBSERVATIONS).
OPTIONAL_OBSERVATIONS = {
    "log_qp_scale": "split_q",
    "log_innovation_power": "innovation_power",
    "log_mean_innovation_power": "innovation_power",
    "log_step_statistic": "step_statistic",
    "log_turn_rate": "turn_rate",
    "log_innovation_bias": "innovation_bias",
}
#: Observations are log10 ratios clipped to ±OBS_LIMIT, except those with a range of their own.
OBS_LIMIT = 8.0
OBS_RANGES = {"whiteness": (-1.0, 1.0), "progress": (0.0, 1.0)}


class Layout(Protocol):
    """The switches of :class:`aeromag_env.environment.env.EnvConfig` that shape the spaces."""

    @property
    def extras(self) -> bool: ...
    @property
    def split_q(self) -> bool: ...
    @property
    def innovation_power(self) -> bool: ...
    @property
    def step_statistic(self) -> bool: ...
    @property
    def turn_rate(self) -> bool: ...
    @property
    def innovation_bias(self) -> bool: ...


def action_names(config: Layout) -> tuple[str, ...]:
    """The entries of one action: ``(a_q, a_r)``, or with ``split_q`` ``(a_q, a_r, a_qp)``."""
    return ACTIONS if config.split_q else BASE_ACTIONS


def action_size(config: Layout) -> int:
    """Entries of one action."""
    return len(action_names(config))


def observation_names(config: Layout) -> tuple[str, ...]:
    """The observations of ``config``, in the order of the observation vector."""
    if not config.extras:
        return BASE_OBSERVATIONS
    optional = OBSERVATIONS[len(BASE_OBSERVATIONS) + len(EXTRA_OBSERVATIONS) :]
    chosen = tuple(n for n in optional if getattr(config, OPTIONAL_OBSERVATIONS[n]))
    return BASE_OBSERVATIONS + EXTRA_OBSERVATIONS + chosen


def observation_index(config: Layout, name: str) -> int:
    """The column of observation ``name`` under ``config`` (ValueError when it has none)."""
    names = observation_names(config)
    if name not in names:
        raise ValueError(f"observation {name!r} is not in this layout: {', '.join(names)}")
    return names.index(name)


def observation_positions(config: Layout) -> np.ndarray:
    """For each name of :data:`OBSERVATIONS`, its column under ``config`` or -1 (int64)."""
    names = observation_names(config)
    return np.array([names.index(n) if n in names else -1 for n in OBSERVATIONS], np.int64)


def observation_bounds(config: Layout) -> tuple[np.ndarray, np.ndarray]:
    """The lower and upper bounds (float32) of the observations of ``config``."""
    ranges = [OBS_RANGES.get(n, (-OBS_LIMIT, OBS_LIMIT)) for n in observation_names(config)]
    low, high = np.array(ranges, np.float32).reshape(-1, 2).T
    return np.ascontiguousarray(low), np.ascontiguousarray(high)


def check_actions(
    actions: object,
    num_envs: int | None = None,
    size: int = len(BASE_ACTIONS),
    out: np.ndarray | None = None,
) -> np.ndarray:
    """The action of one environment as float64 (size,), or with ``num_envs`` the actions of a
    vector environment (num_envs, size), written into ``out`` (float64 (num_envs, size)) if
    given; a one-line ValueError when the size is wrong, the values are not real numbers
    (complex, bool, text, objects) or one is not finite (values outside [-1, 1] are clipped
    later, not refused)."""
    try:
        given = np.asarray(actions)
    except (TypeError, ValueError):
        raise ValueError(f"actions must be numbers in [-1, 1], got {_shown(actions)}") from None
    if given.dtype.kind not in REAL_KINDS:
        raise ValueError(
            f"actions must be real numbers in [-1, 1], got {_kind_name(given.dtype)} "
            f"({given.dtype})"
        )
    if num_envs is None:
        a = given.astype(np.float64, copy=False)
        if a.size != size or not np.all(np.isfinite(a)):
            raise ValueError(f"action must be {size} finite numbers in [-1, 1], got {_shown(a)}")
        return a.reshape(size)
    if given.shape != (num_envs, size):
        raise ValueError(
            f"actions must have shape ({num_envs}, {size}) (one action per environment), "
            f"got shape {given.shape}"
        )
    if out is None:
        a = given.astype(np.float64, copy=False)
    else:
        a = out
        np.copyto(a, given)
    finite = np.isfinite(a)
    if not finite.all():
        i = int(np.flatnonzero(~finite.all(axis=1))[0])
        raise ValueError(f"actions must be finite; environment {i} got {a[i].tolist()}")
    return a


#: numpy dtype kinds an action may have: floating point, signed and unsigned integers.
REAL_KINDS = "fiu"


def _shown(value: object) -> str:
    """``value`` on one line, at most 80 characters (arrays as lists)."""
    text = " ".join(repr(value.tolist() if isinstance(value, np.ndarray) else value).split())
    return text if len(text) <= 80 else text[:77] + "..."


def _kind_name(dtype: np.dtype) -> str:
    names = {
        "c": "complex numbers",
        "b": "booleans",
        "O": "Python objects",
        "U": "text",
        "S": "bytes",
        "M": "dates",
        "m": "time spans",
        "V": "raw records",
    }
    return names.get(dtype.kind, "values")
