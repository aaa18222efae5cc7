"""The action and observation layouts of the tuning environment, named once.

An action is ``[a_q, a_r]``, or with a T_p action (:attr:`ActionSpec.permanent
<aeromag_env.environment.config.ActionSpec.permanent>` ``graded`` or ``gate``) ``[a_q, a_r,
a_qp]`` (:data:`ACTIONS`). An observation is the tuple of registry names the configuration
chooses (:attr:`~aeromag_env.environment.config.EnvConfig.observations`), in that order; its
size, names and bounds come from the registry (:mod:`aeromag_env.environment.observations`)
only. The compiled step writes each observation at the column :func:`observation_positions`
gives it; policies find a column with :func:`observation_index`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from aeromag_env.environment.observations import NAMES, entry

if TYPE_CHECKING:
    from aeromag_env.environment.config import EnvConfig

#: The entries of an action, in order; ``a_qp`` only with a T_p action.
ACTIONS = ("a_q", "a_r", "a_qp")
#: Their positions: Q scale (of every state, or with a T_p action of the A and B blocks), R
#: scale, Q scale of the permanent-field block T_p.
ACT_Q, ACT_R, ACT_QP = ACTIONS.index("a_q"), ACTIONS.index("a_r"), ACTIONS.index("a_qp")
#: The actions without a T_p action.
BASE_ACTIONS = ACTIONS[:2]
#: The columns of the paper's two observations, which every configuration's observation
#: starts with (:func:`aeromag_env.environment.observations.check_observations`).
OBS_LOG_ROR, OBS_LOG_QOQ = 0, 1


def action_names(config: EnvConfig) -> tuple[str, ...]:
    """The entries of one action: ``(a_q, a_r)``, or with a T_p action ``(a_q, a_r, a_qp)``."""
    return ACTIONS[: config.action.size]


def action_size(config: EnvConfig) -> int:
    """Entries of one action."""
    return config.action.size


def observation_names(config: EnvConfig) -> tuple[str, ...]:
    """The observations of ``config``, in the order of the observation vector."""
    return tuple(config.observations)


def observation_index(config: EnvConfig, name: str) -> int:
    """The column of observation ``name`` under ``config`` (ValueError when it has none)."""
    names = observation_names(config)
    if name not in names:
        raise ValueError(f"observation {name!r} is not in this layout: {', '.join(names)}")
    return names.index(name)


def observation_positions(config: EnvConfig) -> np.ndarray:
    """For each registry entry (:data:`aeromag_env.environment.observations.NAMES`), its column
    under ``config`` or -1 (int64)."""
    names = observation_names(config)
    return np.array([names.index(n) if n in names else -1 for n in NAMES], np.int64)


def observation_bounds(config: EnvConfig) -> tuple[np.ndarray, np.ndarray]:
    """The lower and upper bounds (float32) of the observations of ``config``."""
    ranges = [(entry(n).low, entry(n).high) for n in observation_names(config)]
    low, high = np.array(ranges, np.float32).reshape(-1, 2).T
    return np.ascontiguousarray(low), np.ascontiguousarray(high)


def check_actions(
    actions: object,
    num_envs: int | None = None,
    size: int = len(BASE_ACTIONS),
    out: np.ndarray | None = None,
    finite: bool = True,
) -> np.ndarray:
    """The action of one environment as float64 (size,), or with ``num_envs`` the actions of a
    vector environment (num_envs, size), written into ``out`` (float64 (num_envs, size)) if
    given; a one-line ValueError when the size is wrong, the values are not real numbers
    (complex, bool, text, objects) or one is not finite (values outside [-1, 1] are clipped
    later, not refused). With ``finite=False`` (a vector environment's actions only) the values
    are not checked for being finite: the caller's compiled step checks them before it moves
    any environment and raises :func:`non_finite_actions`."""
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
    if finite:
        rows = np.flatnonzero(~np.isfinite(a).all(axis=1))
        if rows.size:
            raise non_finite_actions(int(rows[0]), a)
    return a


def non_finite_actions(i: int, actions: np.ndarray) -> ValueError:
    """The error for the actions (num_envs, size) of a vector environment whose row i is not
    finite."""
    return ValueError(f"actions must be finite; environment {i} got {actions[i].tolist()}")


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
