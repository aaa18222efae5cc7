"""The page of ``aeromag train``: the learning curve of one training run, or of several seeds.

Shown: each run's best validation RMSE (headline figures); validation RMSE against training
steps and against minutes; the validation score (when the run selects by one) against steps.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from aeromag_env.reports import html as h
from aeromag_env.reports.html import COLOURS
from aeromag_env.reports.plots import finish_legend, new_figure


@h.page_builder
def train_page(runs: dict[str, dict[str, Any]], title: str = "Training") -> str:
    """The HTML page of one or more training runs.

    Parameters
    ----------
    runs : dict
        Label → what the run's ``training.json`` holds (``scenario``, ``timesteps``,
        ``best_validation_rmse_nt``, ``curve``: points with ``timesteps``,
        ``validation_rmse_nt`` [nT], ``seconds`` [s] and optionally ``validation_score``).
        With one run its figures are keyed by their name in ``training.json``, with several by
        ``<label>.<name>``.
    title : str

    Returns
    -------
    str
        A self-contained HTML document.
    """
    single = len(runs) == 1
    cards = []
    for label, run in runs.items():
        prefix = "" if single else f"{label}."
        suffix = "" if single else f" ({label})"
        cards.append(
            h.Headline(
                f"best validation RMSE{suffix}",
                f"{prefix}best_validation_rmse_nt",
                run.get("best_validation_rmse_nt"),
                "nT",
            )
        )
        if single:
            cards.append(h.Headline("steps", "timesteps", run.get("timesteps")))
    blocks: list[Any] = [h.headlines(cards), h.heading("Learning curve")]
    steps = new_figure(
        "validation RMSE against training steps", "steps", "validation RMSE [nT]", y_log=True
    )
    minutes = new_figure(
        "validation RMSE against wall-clock time", "minutes", "validation RMSE [nT]", y_log=True
    )
    scored = any(
        p.get("validation_score") is not None for r in runs.values() for p in r.get("curve") or []
    )
    score = (
        new_figure(
            "validation score against training steps (lower is better)",
            "steps",
            "score [-]",
            x_range=steps.x_range,
        )
        if scored
        else None
    )
    for i, (label, run) in enumerate(runs.items()):
        curve = run.get("curve") or []
        colour = COLOURS[i % len(COLOURS)]
        x = np.array([p["timesteps"] for p in curve], dtype=float)
        rmse = np.array([_finite(p.get("validation_rmse_nt")) for p in curve])
        mins = np.array([_finite(p.get("seconds")) for p in curve]) / 60.0
        for fig, xs in ((steps, x), (minutes, mins)):
            fig.line(xs, rmse, color=colour, line_width=2, legend_label=label)
            fig.scatter(xs, rmse, color=colour, size=6, legend_label=label)
        if score is not None:
            values = np.array([_finite(p.get("validation_score")) for p in curve])
            score.line(x, values, color=colour, line_width=2, legend_label=label)
            score.scatter(x, values, color=colour, size=6, legend_label=label)
    figs = [f for f in (steps, minutes, score) if f is not None]
    for fig in figs:
        finish_legend(fig)
    blocks += figs
    first = next(iter(runs.values()))
    blocks += [
        h.heading("Settings"),
        h.card(h.definitions({k: v for k, v in first.items() if k not in ("curve",)})),
    ]
    subtitle = f"scenario {first.get('scenario', '?')} · {len(runs)} run(s)"
    return h.render_page(title, subtitle, blocks)


def _finite(value: Any) -> float:
    return float(value) if value is not None else float("nan")
