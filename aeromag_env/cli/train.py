"""``aeromag train``: one PPO training run, or one per seed (``--seeds 0-4``) side by side.

Each seed trains into ``out/seed_<k>/`` with its own checkpoint up to ``--timesteps`` steps in
all, so a rerun with the same ``--out`` resumes every seed where it stopped (and stops there,
or goes on to a larger ``--timesteps``), and a seed whose Ray worker died is retried from its
last checkpoint. The seeds' summary (best validation RMSE per seed, mean and spread) is
printed and written to ``out/seeds.json``; the test-split table over the seeds is
``python -m experiments.seed_table out/seed_*/policy.npz`` (README, "Running on a cluster").
"""

from __future__ import annotations

import json
import math
import statistics
from pathlib import Path
from typing import Any

from aeromag_env import reports
from aeromag_env.atomic import check_output_set, output_set, write_text
from aeromag_env.cli.limits import check_seed
from aeromag_env.errors import AeromagError
from aeromag_env.parallel import Task, failures, runner

#: The most training runs one ``--seeds`` may ask for.
MAX_SEEDS = 1000


def parse_seeds(text: str) -> list[int]:
    """``--seeds``: ``0-4``, ``0,2,5`` or a mix (``0-2,7``); distinct seeds in the given order."""
    seeds: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.strip().partition("-")
        try:
            first, last = int(lo), int(hi) if hi else int(lo)
        except ValueError:
            raise AeromagError(f"--seeds takes e.g. 0-4 or 0,2,5, got {text!r}") from None
        if last < first or last - first >= MAX_SEEDS:
            raise AeromagError(
                f"--seeds: {part.strip()!r} is not a range of at most "
                f"{MAX_SEEDS} seeds (low-high, low ≤ high)"
            )
        seeds += range(first, last + 1)
    for seed in seeds:
        check_seed("--seeds", seed)
    if len(set(seeds)) < len(seeds) or len(seeds) > MAX_SEEDS:
        raise AeromagError(f"--seeds must name at most {MAX_SEEDS} distinct seeds, got {text!r}")
    return seeds


def train_seeds(
    scenario: str,
    timesteps: int | None,
    seeds: list[int],
    out: Path,
    quick: bool,
    hyperparams: Path | None,
    ray: str | None,
    quiet: bool,
    html: bool = True,
) -> dict[str, Any]:
    """Train one run per seed (tasks of ``--ray``'s runner, one CPU each); write and return
    the summary (and with ``html`` the seeds' learning curves, ``report.html``). A failed
    seed is reported with its folder and the rest complete; then the error is raised."""
    from tqdm import tqdm

    from agents.ppo import CHECKPOINT, HYPERPARAMS, OUTPUTS, train_ppo

    hp = hyperparams or HYPERPARAMS
    for seed in seeds:
        check_output_set(out / f"seed_{seed}", (*CHECKPOINT, *OUTPUTS), [hp])
    outputs = ("seeds.json", reports.PAGE) if html else ("seeds.json",)
    check_output_set(out, outputs, [hp])
    tasks = [
        Task(
            f"seed {seed} ({out / f'seed_{seed}'})",
            train_ppo,
            (scenario, timesteps, seed, out / f"seed_{seed}", quick, False, hp, True),
        )
        for seed in seeds
    ]
    with (
        runner(ray) as r,
        tqdm(
            total=len(seeds), desc="training seeds", unit="seed", disable=quiet or None, leave=False
        ) as bar,
    ):
        outcomes = r.run(tasks, lambda o: bar.update(1))
    rows = [
        {
            "seed": seed,
            "folder": str(out / f"seed_{seed}"),
            "attempts": o.attempts,
            "best_validation_rmse_nt": o.value["best_validation_rmse_nt"] if o.ok else None,
            "timesteps": o.value["timesteps"] if o.ok else None,
            "error": o.error,
        }
        for seed, o in zip(seeds, outcomes, strict=True)
    ]
    summary = {"scenario": scenario, "runner": r.name, "seeds": rows, **_spread(rows)}
    with output_set(out, outputs, [hp]) as stage:
        write_text(stage / "seeds.json", json.dumps(summary, indent=2))
        if html:
            runs = {f"seed {s}": o.value for s, o in zip(seeds, outcomes, strict=True) if o.ok}
            write_text(stage / reports.PAGE, reports.train_page(runs, f"Training: {scenario}"))
    print(seed_table(summary))
    failed = failures(outcomes)
    if failed:
        raise AeromagError(
            f"{len(failed)} of {len(seeds)} training run(s) failed; first: "
            f"{failed[0].label}: {failed[0].error}"
        )
    return summary


def _spread(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Mean and SD of the seeds' finite best validation RMSEs (SD from 2 seeds on)."""
    finite = [
        v for r in rows if (v := r["best_validation_rmse_nt"]) is not None and math.isfinite(v)
    ]
    sd = statistics.stdev(finite) if len(finite) > 1 else None
    return {
        "validation_rmse_nt_mean": statistics.fmean(finite) if finite else None,
        "validation_rmse_nt_sd": sd,
    }


def seed_table(summary: dict[str, Any]) -> str:
    """Markdown: per seed its best validation RMSE, attempts and error; then mean and SD."""
    lines = [
        "| seed | best validation RMSE [nT] | steps | attempts | error |",
        "|---|---|---|---|---|",
    ]
    for r in summary["seeds"]:
        rmse = r["best_validation_rmse_nt"]
        shown = "—" if rmse is None else f"{rmse:.3g}"
        attempts = "unknown" if r["attempts"] is None else r["attempts"]
        lines.append(
            f"| {r['seed']} | {shown} | {r['timesteps'] or '—'} | {attempts} | {r['error'] or ''} |"
        )
    mean, sd = summary["validation_rmse_nt_mean"], summary["validation_rmse_nt_sd"]
    if sd is not None:
        lines += ["", f"over {len(summary['seeds'])} seeds: mean {mean:.3g} nT, SD {sd:.2g} nT"]
    retried = [str(r["seed"]) for r in summary["seeds"] if (r["attempts"] or 0) > 1]
    if retried:
        lines.append(f"retried after a worker died: seed(s) {', '.join(retried)}")
    if any(r["attempts"] is None for r in summary["seeds"]):
        lines.append("retries unknown: the Ray actor counting attempts died during the run")
    return "\n".join(lines) + "\n"
