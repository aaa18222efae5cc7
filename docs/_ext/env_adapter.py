"""The one place where the documentation reads the environment's observation and action layouts.

Everything the environment pages show about an observation or an action (its name, bounds,
meaning and the setting that adds it) comes through :func:`observation_entries`,
:func:`action_entries` and :func:`all_observations_overrides`. Today they read
:mod:`aeromag_env.environment.spaces` (names, bounds, the switch of each optional observation)
and take each observation's meaning from the comment beside its name in ``OBSERVATIONS``; when
the environment carries a registry of observations with their descriptions, these three
functions are all that changes.
"""

from __future__ import annotations

import inspect
import io
import tokenize
from dataclasses import dataclass
from functools import cache
from typing import Any

from aeromag_env.environment import spaces


@dataclass(frozen=True)
class Entry:
    """One column of an observation or action vector, as the pages show it."""

    name: str
    low: float
    high: float
    meaning: str
    switch: str  # the setting that adds it ("" when always present)


def observation_entries(config: Any) -> list[Entry]:
    """The observations of an environment configured by ``config``, in the vector's order."""
    names = spaces.observation_names(config)
    low, high = spaces.observation_bounds(config)
    extras = set(spaces.EXTRA_OBSERVATIONS)
    return [
        Entry(
            name,
            float(lo),
            float(hi),
            _observation_comments().get(name, ""),
            spaces.OPTIONAL_OBSERVATIONS.get(name, "extras" if name in extras else ""),
        )
        for name, lo, hi in zip(names, low, high, strict=True)
    ]


def all_observations_overrides() -> dict[str, bool]:
    """Settings (keywords of ``gym.make``) under which every observation is given."""
    return {"extras": True, **{s: True for s in spaces.OPTIONAL_OBSERVATIONS.values()}}


#: What each action entry does (ACTIONS names them; tests/test_docs.py keeps the keys equal).
ACTION_MEANINGS = {
    "a_q": "scales Q: ``Q ← s_max ** a_q · Q`` (with ``split_q``, the Q of the induced and "
    "eddy-current blocks only)",
    "a_r": "scales R: ``R ← s_max ** a_r · R``",
    "a_qp": "scales the Q of the permanent-field block T_p (with ``qp_gate``, only its sign "
    "counts)",
}


def action_entries(config: Any) -> list[Entry]:
    """The entries of one action of an environment configured by ``config``."""
    return [
        Entry(name, -1.0, 1.0, ACTION_MEANINGS.get(name, ""), "split_q" if name == "a_qp" else "")
        for name in spaces.action_names(config)
    ]


@cache
def _observation_comments() -> dict[str, str]:
    """Each name of ``spaces.OBSERVATIONS`` → the comment written beside it in the source."""
    source = inspect.getsource(spaces)
    comments: dict[str, str] = {}
    inside, last = False, ""
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.NAME and tok.string == "OBSERVATIONS" and tok.start[1] == 0:
            inside = True
        elif inside and tok.type == tokenize.STRING:
            last = tok.string.strip("\"'")
        elif inside and tok.type == tokenize.COMMENT and last:
            comments[last] = tok.string.lstrip("# ").strip()
            last = ""
        elif inside and tok.type == tokenize.OP and tok.string == ")":
            break
    return comments
