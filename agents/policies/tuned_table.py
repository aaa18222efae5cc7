"""The stored ``tuned_constant`` table: scenario → best constant Q and R scales.

Written by :func:`agents.search.tuned_constant.tune_constant` through
``experiments/tune_constants.py``, read by
:class:`agents.policies.baselines.TunedConstantPolicy`.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from aeromag_env.errors import AeromagError

TABLE = Path(__file__).with_name("tuned_constants.json")


def load_tuned(path: Path = TABLE) -> dict[str, dict[str, Any]]:
    """The stored table: scenario → ``{"log10_q", "log10_r", ...}``."""
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as e:
        raise AeromagError(f"cannot read the tuned-constant table {path}: {e}") from None
