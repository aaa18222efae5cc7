"""The one place where the documentation reads the environment's observation and action layouts.

Everything the environment pages show about an observation or an action (its name, bounds,
meaning and what adds it) comes through :func:`observation_entries`, :func:`action_entries` and
:func:`all_observations_overrides`, which read the observation registry
(:mod:`aeromag_env.environment.observations`) and the action names of
:mod:`aeromag_env.environment.spaces`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from aeromag_env.environment import observations, spaces


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
    return [
        Entry(name, float(lo), float(hi), _meaning(name), _added_by(name))
        for name, lo, hi in zip(names, low, high, strict=True)
    ]


def _meaning(name: str) -> str:
    """The registry's description of ``name`` with its unit."""
    entry = observations.entry(name)
    return f"{entry.description} [{entry.unit}]"


def _added_by(name: str) -> str:
    """What adds ``name`` to the observation: always there (the paper's), or its name in
    ``observations`` (and what else it needs)."""
    if name in observations.PAPER_OBSERVATIONS:
        return ""
    needs = observations.entry(name).needs
    return "observations" + (f" + {', '.join(needs)}" if needs else "")


def all_observations_overrides() -> dict[str, Any]:
    """Settings (keywords of ``gym.make``) under which every observation of the registry is
    given: the ``general`` preset's."""
    return {"preset": "general"}


#: What each action entry does (ACTIONS names them; tests/test_docs.py keeps the keys equal).
ACTION_MEANINGS = {
    "a_q": "scales Q: ``Q ← s_max ** a_q · Q`` (with a separate T_p action, the Q of the "
    "induced and eddy-current blocks only)",
    "a_r": "scales R: ``R ← s_max ** a_r · R``",
    "a_qp": "scales the Q of the permanent-field block T_p (``action.permanent`` ``graded``; "
    "with ``gate`` only its sign counts)",
}


def action_entries(config: Any) -> list[Entry]:
    """The entries of one action of an environment configured by ``config``."""
    return [
        Entry(
            name,
            -1.0,
            1.0,
            ACTION_MEANINGS.get(name, ""),
            "action.permanent" if name == "a_qp" else "",
        )
        for name in spaces.action_names(config)
    ]
