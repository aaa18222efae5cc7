"""``aeromag train``: one PPO training run, or one per seed (``--seeds 0-4``) side by side.

Each seed trains into ``out/seed_<k>/`` with its own checkpoint up to ``--timesteps`` steps in
all, so a rerun with the same ``--out`` resumes every seed where it stopped (and stops there,
or goes on to a larger ``--timesteps``), and a seed whose Ray worker died is retried from its
last checkpoint. The seeds' summary (best validation RMSE per seed, mean and spread) is
printed and written to ``out/seeds.json``; the test-split table over the seeds is
``python -m experiments.seed_table out/seed_*/policy.npz`` (README, "Running on a cluster").
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from aeromag_env.cli.limits import check_seed
from aeromag_env.errors import AeromagError

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
    learner: str = "ppo",
) -> dict[str, Any]:
    """Train one run per seed (:func:`agents.jobs.train_policies`) with a progress bar, print
    the seeds' table and return the summary. A failed seed is reported with its folder and the
    rest complete; then the error is raised."""
    from tqdm import tqdm

    from agents.jobs import train_policies

    with tqdm(
        total=len(seeds), desc="training seeds", unit="seed", disable=quiet or None, leave=False
    ) as bar:
        done = train_policies(
            scenario,
            seeds,
            out,
            timesteps,
            quick,
            hyperparams,
            ray,
            html,
            progress=lambda o: bar.update(1),
            learner=learner,
        )
    print(seed_table(done.summary))
    if done.failed:
        first = done.failed[0]
        raise AeromagError(
            f"{len(done.failed)} of {len(seeds)} training run(s) failed; first: "
            f"{first.label}: {first.error}"
        )
    return done.summary


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
