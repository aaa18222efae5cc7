"""The adaptive filters' benchmark: every policy on the same fresh test flights of every scenario.

``python experiments/adaptive_benchmark.py [--episodes 30] [--first-seed 400000] [--scenarios
...] [--policies ...] [--resume] [--out FILE] [--quick]`` flies ``constant``, ``fis``,
``sage_husa``, ``ding``, ``vbakf``, ``vbakf_pr``, ``imm``, ``tuned_constant``,
``tuned_constant_suite``, ``general`` and ``privileged`` (``agents.comparison.adaptive.
BENCHMARK_POLICIES``) on test seeds ``first-seed … first-seed + episodes − 1`` of every scenario
(``agents.evaluation.seeds.ADAPTIVE_BENCHMARK_FIRST_SEED``: a range no earlier table flew), and
writes every flight's RMSE and divergences with the tables (mean RMSE, worst 10 %, normalized
score with paired intervals, divergences, paired differences against ``constant``,
``tuned_constant`` and ``general``), the seeds and each run's command, date and seconds, to
``--out`` (default
``docs/results/adaptive_benchmark.json``, from which ``python scripts/results_pages.py`` makes
``docs/results/adaptive.md``). ``--resume`` keeps the pairs ``--out`` already holds (same seeds)
and flies the rest. ``--quick``: 2 scenarios, 2 flights, 4 policies unless ``--policies`` names
them, into ``results/adaptive_benchmark.json`` by default.
"""

from __future__ import annotations

import argparse
import datetime
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import aeromag_env
from aeromag_env.atomic import write_text
from aeromag_env.environment.ids import SCENARIOS
from aeromag_env.errors import AeromagError
from agents.comparison.adaptive import BENCHMARK_POLICIES, fly, summarize
from agents.evaluation.seeds import ADAPTIVE_BENCHMARK_FIRST_SEED
from agents.training.quick import QUICK

OUT, QUICK_OUT = (
    Path("docs/results/adaptive_benchmark.json"),
    Path("results/adaptive_benchmark.json"),
)
QUICK_POLICIES = ("constant", "vbakf", "tuned_constant", "privileged")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--episodes", type=int, default=30, help="flights per scenario (30)")
    parser.add_argument("--first-seed", type=int, default=ADAPTIVE_BENCHMARK_FIRST_SEED)
    parser.add_argument("--scenarios", default=",".join(SCENARIOS), help="comma-separated")
    parser.add_argument(
        "--policies", default=None, help="comma-separated (default: all of the benchmark's)"
    )
    parser.add_argument("--resume", action="store_true", help="keep the pairs --out holds")
    parser.add_argument("--out", type=Path, default=None, help=f"results file ({OUT})")
    parser.add_argument("--quick", action="store_true", help="2 scenarios, 2 flights (tests)")
    args = parser.parse_args(argv)
    default = QUICK_POLICIES if args.quick else BENCHMARK_POLICIES
    scenarios = args.scenarios.split(",")
    policies = args.policies.split(",") if args.policies else list(default)
    episodes, out = args.episodes, args.out or (QUICK_OUT if args.quick else OUT)
    if args.quick:
        scenarios, episodes = scenarios[: QUICK.scenarios], QUICK.episodes
    seeds = list(range(args.first_seed, args.first_seed + episodes))
    try:
        old = _earlier(out, seeds) if args.resume else {}
        t0 = time.perf_counter()
        flights = fly(scenarios, policies, seeds, old.get("flights"), progress=_progress)
    except AeromagError as e:
        print(f"adaptive_benchmark: {e}", file=sys.stderr)
        return 2
    words = sys.argv[1:] if argv is None else list(argv)
    run = {
        "command": " ".join(["python experiments/adaptive_benchmark.py", *words]),
        "date": datetime.date.today().isoformat(),
        "package_version": aeromag_env.__version__,
        "seconds": round(time.perf_counter() - t0),
    }
    record = {
        "runs": [*old.get("runs", []), run],
        "seeds": seeds,
        "scenarios": list(flights),
        "policies": list(dict.fromkeys(p for per in flights.values() for p in per)),
        "tables": summarize(flights),
        "flights": flights,
    }
    write_text(out, json.dumps(record, indent=1) + "\n")
    print(f"wrote {out}")
    return 0


def _earlier(out: Path, seeds: list[int]) -> dict:
    """The record of ``out`` when it exists and was flown on ``seeds`` (its ``runs`` and
    ``flights``); empty when it does not exist."""
    if not out.exists():
        return {}
    old = json.loads(out.read_text())
    if old.get("seeds") != seeds:
        raise AeromagError(f"--resume: {out} was flown on other seeds; give its --episodes")
    return old


def _progress(scenario: str, policy: str, seconds: float) -> None:
    print(f"{scenario}/{policy}: {seconds:.0f} s", flush=True)


if __name__ == "__main__":
    raise SystemExit(main())
