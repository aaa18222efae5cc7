"""The values the jobs' arguments choose among, in one light module: the command line builds its
``--help`` and its choices from these without loading the jobs themselves (and ``agents`` only
for the learners' names, which its package's face holds)."""

from __future__ import annotations

from aeromag_env.compensation.compensate import METHODS
from aeromag_env.compensation.model_fit import FIT_METHODS
from aeromag_env.discovery.ground import GROUND_MODES
from aeromag_env.simulation.config import PATTERNS, PRESETS
from agents.training import LEARNERS

#: The filter settings ``compensate``'s ``filter_preset`` names: the package defaults or the
#: paper's §4 setting.
FILTER_PRESETS = ("default", "paper")
#: What ``bench``'s ``only`` may measure alone.
BENCH_ONLY = ("ray", "discover", "ppo", "stream")

__all__ = [
    "BENCH_ONLY",
    "FILTER_PRESETS",
    "FIT_METHODS",
    "GROUND_MODES",
    "LEARNERS",
    "METHODS",
    "PATTERNS",
    "PRESETS",
]
