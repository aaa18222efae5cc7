"""The stored tuned constants: per scenario (``tuned_constant``) and one for the whole suite
(``tuned_constant_suite``).

The per-scenario table (scenario → best constant Q and R scales) is written by
:func:`agents.search.tuned_constant.tune_constant` through ``experiments/tune_constants.py``
and read by :class:`agents.policies.baselines.TunedConstantPolicy`; the suite's constant by
:func:`agents.search.tuned_constant.tune_constant_suite` through ``experiments/tune_constants.py
--suite`` and read by :class:`agents.policies.baselines.TunedConstantSuitePolicy`.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from aeromag_env.errors import AeromagError

TABLE = Path(__file__).with_name("tuned_constants.json")
SUITE_TABLE = Path(__file__).with_name("tuned_constant_suite.json")


def load_tuned(path: Path = TABLE) -> dict[str, dict[str, Any]]:
    """The stored table: scenario → ``{"log10_q", "log10_r", ...}``."""
    return _read(path, "tuned-constant table")


def load_suite(path: Path = SUITE_TABLE) -> dict[str, Any]:
    """The stored suite constant: ``{"log10_q", "log10_r", "seeds", "scenarios", "command",
    "date", ...}``; a file without finite ``log10_q`` and ``log10_r`` is refused in one line."""
    record = _read(path, "suite's tuned constant")
    values = [record.get(k) if isinstance(record, dict) else None for k in ("log10_q", "log10_r")]
    if not all(isinstance(v, int | float) and math.isfinite(v) for v in values):
        raise AeromagError(f"the suite's tuned constant {path} needs finite log10_q and log10_r")
    return record


def _read(path: Path, what: str) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as e:
        raise AeromagError(f"cannot read the {what} {path}: {e}") from None
