"""The learners' benchmark: train every learner over seeds, fly the test flights, choose and ship.

The steps are :mod:`agents.comparison.pipeline`'s; each is resumable by its files::

    python experiments/compare_learners.py train --learners recurrent_ppo,sac --seeds 0-4
    python experiments/compare_learners.py evaluate --episodes 30 [--ray [ADDRESS]]
    python experiments/compare_learners.py select [--flights 8] [--ray [ADDRESS]]
    python experiments/compare_learners.py ship [--to PATH]

The runs go to ``--runs`` (default ``results/learners``), the data ``evaluate`` and ``select``
write to ``--data`` (default ``RUNS/data``) and ``ship`` writes ``--to`` (default
``RUNS/ppo_general.npz``). The committed data and the shipped policy are written only when
named: ``--data docs/learners`` (then ``python scripts/results_pages.py`` makes the page) and
``ship --to agents/policies/trained/ppo_general.npz``. ``--quick`` on train, evaluate and select:
test-sized. Each step prints its minutes, ``train`` each run's; how long the full steps take on
these 2-core machines is in ``docs/howto/learners.md`` (hours for ``train``, about half an hour
for ``evaluate --episodes 30`` in one process).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.errors import AeromagError
from aeromag_env.parallel import Outcome, runner
from aeromag_env.quick import add_quick_option
from agents.comparison import pipeline
from agents.training import LEARNERS
from agents.training.quick import QUICK

RUNS = Path("results/learners")
COMMAND = "python -m experiments.compare_learners"


def seeds_arg(text: str) -> list[int]:
    """``0-4`` or ``0,2,5``."""
    try:
        if "-" in text:
            lo, hi = text.split("-", 1)
            return list(range(int(lo), int(hi) + 1))
        return [int(s) for s in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: a range 0-4 or a list 0,2,5") from None


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    sub = parser.add_subparsers(dest="step", required=True)
    t = sub.add_parser("train", help="train learners × seeds into RUNS")
    t.add_argument("--learners", default=",".join(LEARNERS), help="comma-separated")
    t.add_argument("--seeds", default="0-4", type=seeds_arg, help="0-4 or 0,2,5")
    e = sub.add_parser("evaluate", help="fly the test flights, write the data to DATA")
    e.add_argument("--episodes", type=int, default=30, help="test flights per scenario")
    e.add_argument("--first-seed", type=int, default=pipeline.FIRST_SEED)
    c = sub.add_parser("select", help="choose the policy to ship, on validation flights")
    c.add_argument("--flights", type=int, default=8, help="validation flights per scenario")
    h = sub.add_parser("ship", help="write the chosen policy as a general policy file")
    h.add_argument("--to", type=Path, help="the policy file (default RUNS/ppo_general.npz)")
    for p in (t, e, c, h):
        p.add_argument("--runs", type=Path, default=RUNS, help="the runs' folder")
    for p in (t, e, c):
        add_quick_option(p, "test-sized (about a minute a step)")
        p.add_argument("--ray", nargs="?", const="local", metavar="ADDRESS", help="on Ray")
    for p in (e, c, h):
        p.add_argument("--data", type=Path, help="the data folder (default RUNS/data)")
    return parser


def _trained(outcome: Outcome) -> None:
    if not outcome.ok:
        print(f"{outcome.label}: {outcome.error}", flush=True)
        return
    minutes = outcome.value["train_seconds_this_run"] / 60.0
    when = "trained" if outcome.value["trained_now"] else "finished before"
    print(f"{outcome.label}: {when}, {minutes:.1f} min", flush=True)


def _step(args: argparse.Namespace, argv: Sequence[str]) -> int:
    """Run the step ``args`` name; its exit status."""
    data = getattr(args, "data", None) or args.runs / "data"
    command = " ".join([COMMAND, *argv])
    if args.step == "train":
        learners = args.learners.split(",")
        with runner(args.ray) as tasks:
            outcomes = pipeline.train(
                learners, args.seeds, args.runs, tasks, quick=args.quick, progress=_trained
            )
        return 0 if all(o.ok for o in outcomes) else 1
    if args.step == "evaluate":
        episodes = QUICK.episodes if args.quick else args.episodes
        with runner(args.ray) as tasks:
            done = pipeline.evaluate(
                args.runs,
                data,
                tasks,
                episodes=episodes,
                first_seed=args.first_seed,
                command=command,
            )
        print(f"wrote {', '.join(map(str, done.files))} and {done.policies} policies")
        return 0
    if args.step == "select":
        with runner(args.ray) as tasks:
            flights = 1 if args.quick else args.flights
            result = pipeline.select(args.runs, data, tasks, flights=flights, command=command)
        for learner, mean in sorted(result["learner_mean_score"].items(), key=lambda kv: kv[1]):
            print(f"{learner:15s} mean validation score {mean:.3f}")
        print(f"chosen: {result['chosen']['learner']} seed {result['chosen']['seed']}")
        return 0
    print(pipeline.ship(args.runs, data, args.to or args.runs / "ppo_general.npz"))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    args = _parser().parse_args(argv)
    t0 = time.perf_counter()
    try:
        status = _step(args, argv)
    except AeromagError as e:
        print(f"compare_learners {args.step}: {e}", file=sys.stderr)
        return 2
    print(f"{args.step}: {(time.perf_counter() - t0) / 60:.1f} min")
    return status


if __name__ == "__main__":
    raise SystemExit(main())
