"""The report files of the jobs: strict JSON (NaN and infinities as ``null``)."""

from __future__ import annotations

import json
from typing import Any

import numpy as np


def jsonable(obj: Any) -> Any:
    """``obj`` with NaN/inf replaced by None and numpy scalars by Python's, for strict JSON."""
    if isinstance(obj, dict):
        return {k: jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, (float, np.floating)):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def report_json(report: dict[str, Any]) -> str:
    """The text of a ``report.json``: :func:`jsonable`, indented by 2."""
    return json.dumps(jsonable(report), indent=2)
