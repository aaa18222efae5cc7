"""Train the PPO tuner, ship it, and compare it with every baseline on held-out test flights.

``python experiments/train_ppo.py [--timesteps 3000000] [--episodes 100] [--skip-training]
[--ship] [--quick] [--out results/ppo_experiment]``

1. ``aeromag train`` on ``nonstationary`` (training seeds < 50 000; best policy by validation
   RMSE on the first ``eval_episodes`` validation seeds from 50 000), unless ``--skip-training``;
2. ``--ship`` copies the best policy to ``agents/policies/trained/ppo_nonstationary.npz`` (the
   shipped policy: only when asked);
3. evaluates every policy on test seeds from 100 000 on ``nonstationary`` and ``nominal``;
4. writes ``comparison.md``, ``learning_curve.png`` and the per-scenario results.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from collections.abc import Sequence
from pathlib import Path

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.atomic import write_text
from aeromag_env.jobs.evaluate import evaluate, evaluation_table
from aeromag_env.quick import add_quick_option
from agents.policies import DEFAULT_PPO, POLICIES
from agents.training.quick import QUICK


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--timesteps", type=int, help="default 3e6 (--quick: agents.training.quick)"
    )
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--skip-training", action="store_true")
    parser.add_argument(
        "--ship", action="store_true", help="copy the policy into agents/policies/trained"
    )
    add_quick_option(parser, "tiny run (tests)")
    parser.add_argument(
        "--policy", help="evaluate this exported policy (default OUT/train/policy.npz)"
    )
    parser.add_argument("--out", default="results/ppo_experiment")
    args = parser.parse_args(argv)
    out, t0 = Path(args.out), time.perf_counter()
    train_dir = out / "train"
    if not args.skip_training:
        from agents.training.ppo import train_ppo

        summary = train_ppo(  # --quick: agents.training.quick.QUICK's sizes
            "nonstationary", args.timesteps, 0, train_dir, quick=args.quick, progress=False
        )
        print(f"training: {summary['timesteps']} steps, {summary['train_seconds_this_run']:.0f} s")
    policy = Path(args.policy) if args.policy else train_dir / "policy.npz"
    if args.ship:
        DEFAULT_PPO.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(policy, DEFAULT_PPO)
    episodes = QUICK.episodes if args.quick else args.episodes
    names = [p if p != "ppo" else f"ppo:{policy}" for p in POLICIES]
    tables = []
    for scenario in ("nonstationary", "nominal"):
        res = evaluate(scenario, names, episodes=episodes, out=out / scenario).results[scenario]
        tables.append(evaluation_table(res))
    write_text(out / "comparison.md", "\n".join(tables))
    _learning_curve(policy.with_name("training.json"), out / "learning_curve.png")
    minutes = (time.perf_counter() - t0) / 60
    print(f"wrote {out}/comparison.md, learning_curve.png ({minutes:.1f} min in all)")
    return 0


def _learning_curve(training: Path, path: Path) -> None:
    if not training.exists():
        return
    from aeromag_env.flight.plot import pyplot

    summary = json.loads(training.read_text())
    curve, flights = summary["curve"], summary["hyperparams"]["eval_episodes"]
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4), constrained_layout=True)
    ax.plot([c["timesteps"] for c in curve], [c["validation_rmse_nt"] for c in curve], "o-")
    ax.set(
        xlabel="environment steps",
        ylabel=f"validation RMSE [nT] ({flights} flights)",
        title="PPO on nonstationary: learning curve",
        yscale="log",
    )
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
