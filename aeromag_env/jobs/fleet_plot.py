"""Figure of a fleet run, ``fleet.png``: each flight's figures side by side (matplotlib, lazily).

``compensate``: the band-passed std of the field before and after compensation [nT] and the
improvement ratio; ``discover``: the held-out gap with the base model and with the named
effects [nT]. A failed flight keeps its row, marked ``failed``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.flight.plot import pyplot

#: Per command: the two columns drawn as bars, their labels, the x-axis label and the title.
BARS = {
    "compensate": (
        ("std_uncompensated_nt", "uncompensated"),
        ("std_compensated_nt", "compensated"),
        "band-passed std, 0.1–0.9 Hz, second half [nT]",
        "compensate: each flight before and after",
    ),
    "discover": (
        ("gap_before_nt", "base model"),
        ("gap_after_nt", "with named effects"),
        "held-out gap above the white-noise floor [nT]",
        "discover: each flight's held-out gap",
    ),
}


def _values(rows: list[dict[str, Any]], key: str) -> np.ndarray:
    """The column ``key`` as floats, NaN where a row has none (a failed flight)."""
    out = []
    for row in rows:
        v = row.get(key) if row.get("status") == "ok" else None
        out.append(float(v) if v is not None and math.isfinite(float(v)) else math.nan)
    return np.array(out)


def plot_fleet(rows: list[dict[str, Any]], command: str, path: Path) -> Path:
    """Horizontal bars per flight (:data:`BARS`); the ratio after/before or the failure as text.

    Parameters
    ----------
    rows : list of dict
        The summary rows of ``fleet.csv`` (``output``, ``status`` and the drawn columns).
    command : str
        ``compensate`` or ``discover``.
    path : Path
        PNG file to write (the caller writes it inside an output set).
    """
    plt = pyplot()
    (a, a_label), (b, b_label), xlabel, title = BARS[command]
    before, after = _values(rows, a), _values(rows, b)
    y = np.arange(len(rows))
    fig, ax = plt.subplots(figsize=(9, 1.2 + 0.45 * len(rows)), constrained_layout=True)
    ax.barh(y - 0.2, np.nan_to_num(before), height=0.4, label=a_label, color="tab:gray")
    ax.barh(y + 0.2, np.nan_to_num(after), height=0.4, label=b_label, color="tab:blue")
    for i, row in enumerate(rows):
        if row.get("status") != "ok":
            ax.text(0, i, "  failed: see fleet.csv", va="center", color="tab:red", fontsize=8)
        elif np.isfinite(before[i]) and np.isfinite(after[i]) and after[i] > 0:
            ax.text(
                max(before[i], after[i]),
                i,
                f"  ×{before[i] / after[i]:.3g}",
                va="center",
                fontsize=8,
            )
    ax.set_yticks(y, [str(row.get("output", "")) for row in rows])
    ax.invert_yaxis()
    ax.set(xlabel=xlabel, title=f"{title} ({len(rows)} flights)")
    ax.legend(loc="lower right", fontsize=8)
    fig.savefig(path, dpi=100, format="png")
    plt.close(fig)
    return path
