"""The main job, end to end, in under a minute: :func:`demo`, the job of ``aeromag demo``.

Simulates a 30-minute ``nominal`` calibration flight, compensates it with the paper's filters
(plain and fuzzy adaptive), the offline batch least squares and the industry Tolles–Lawson fit,
then evaluates the baseline tuning policies in the environment on a few ``nonstationary`` test
flights; writes the flight, figures, and a summary table (Markdown and JSON).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aeromag_env.atomic import check_output_set, output_set, write_text
from aeromag_env.compensation.compensate import compensate_scalar, compensate_vector, score
from aeromag_env.compensation.model import FilterConfig
from aeromag_env.compensation.plots import plot_compensation
from aeromag_env.compensation.tolles_lawson import TollesLawson
from aeromag_env.flight.files import write_flight
from aeromag_env.flight.plot import plot_flight
from aeromag_env.jobs.limits import check_seed
from aeromag_env.simulation.config import preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight

DEMO_METHODS = ("kf", "fakf", "lsq", "tl")
DEMO_EPISODES = 5
#: The output set of ``aeromag demo``, in the folder ``--out``.
OUTPUTS = (
    "flight.h5",
    "flight.png",
    *(f"compensation_{m}.png" for m in DEMO_METHODS),
    "tuners.png",
    "summary.md",
    "summary.json",
)


@dataclass(frozen=True)
class DemoResult:
    """What :func:`demo` produced.

    Attributes
    ----------
    summary : dict
        ``summary.json``'s content: the seed, each method's figures of merit, the tuners'
        evaluation (``results.json`` layout).
    text : str
        ``summary.md``: the methods' table and the tuners' table.
    paths : tuple of Path
        The files written (:data:`OUTPUTS`).
    """

    summary: dict[str, Any]
    text: str
    paths: tuple[Path, ...]


def demo(out: str | Path = "results/demo", *, seed: int = 0) -> DemoResult:
    """Run the demo, as ``aeromag demo`` does; the files (:data:`OUTPUTS`) are written as a set
    (:func:`aeromag_env.atomic.output_set`).

    Parameters
    ----------
    out : str or Path
        The output folder.
    seed : int
        The calibration flight's seed, in ``[0, 2³² − 1]``.

    Returns
    -------
    DemoResult

    Raises
    ------
    AeromagError
        A seed outside its range or an output that is not writable (one line), before the work.
    """
    check_seed("seed", seed)
    folder = Path(out)
    check_output_set(folder, OUTPUTS)
    with output_set(folder, OUTPUTS) as stage:
        summary = _run_demo(stage, seed)
    text = (folder / "summary.md").read_text(encoding="utf-8")
    return DemoResult(summary, text, tuple(folder / name for name in OUTPUTS))


def _run_demo(out: Path, seed: int) -> dict[str, Any]:
    cfg = with_overrides(preset("nominal"), {"trajectory.duration_s": 1800.0})
    flight = simulate_flight(cfg, seed)
    write_flight(flight, out / "flight.h5")
    plot_flight(flight, out / "flight.png", title=f"nominal calibration flight, seed {seed}")
    rows = {}
    for method in DEMO_METHODS:
        if method == "tl":
            comp = compensate_scalar(flight, "flux_a", "mag_1_uc", TollesLawson())
        else:
            cfg_f = None if method == "lsq" else FilterConfig(method=method)
            comp = compensate_vector(flight, method, "flux_a", cfg_f)
        rows[method] = score(flight, comp)
        plot_compensation(flight, comp, rows[method], out / f"compensation_{method}.png")
    tuners = _evaluate_tuners(out)
    write_text(out / "summary.md", _table(rows, seed) + "\n" + tuners["table"])
    summary = {"seed": seed, "metrics": rows, "tuners": tuners["results"]}
    write_text(out / "summary.json", json.dumps(summary, indent=2))
    return summary


def _evaluate_tuners(out: Path) -> dict[str, Any]:
    """The baseline tuning policies on a few ``nonstationary`` test flights (seeds ≥ 100 000)."""
    from aeromag_env.jobs.evaluate import evaluation_table
    from agents.evaluation.episodes import evaluate
    from agents.evaluation.plots import plot_evaluation
    from agents.evaluation.seeds import TEST_SEED_START
    from agents.policies import available_policies

    seeds = list(range(TEST_SEED_START, TEST_SEED_START + DEMO_EPISODES))
    results = evaluate("nonstationary", available_policies(), seeds)
    plot_evaluation(results, out / "tuners.png")
    return {"results": results, "table": evaluation_table(results)}


def _table(rows: dict[str, dict[str, Any]], seed: int) -> str:
    lines = [
        f"nominal calibration flight, 1800 s, seed {seed}",
        "",
        "| method | RMSE vs truth (2nd half) [nT] | improvement ratio | FOM (last box) [nT] |",
        "|---|---|---|---|",
    ]
    for method, m in rows.items():
        lines.append(
            f"| {method} | {m['compensation_rmse_nt']:.3g} | {m['improvement_ratio']:.3g} | "
            f"{m['fom_nt']:.3g} (uncompensated {m['fom_uncompensated_nt']:.3g}) |"
        )
    lines += ["", "kf, fakf, lsq: vector fluxgate (flux_a); tl: scalar stinger (mag_1_uc)."]
    return "\n".join(lines) + "\n"
