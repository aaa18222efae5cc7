"""The learners' benchmark: train every learner over seeds, fly the test flights, write the data.

Four steps, each resumable by its files::

    python -m experiments.compare_learners train --learners recurrent_ppo,sac --seeds 0-4 \\
        [--out results/learners] [--ray [ADDRESS]]
    python -m experiments.compare_learners evaluate [--runs results/learners] \\
        [--episodes 30] [--first-seed 200000] [--data docs/learners] [--ray [ADDRESS]]
    python -m experiments.compare_learners select [--runs results/learners] \
        [--flights 8] [--data docs/learners] [--ray [ADDRESS]]
    python -m experiments.compare_learners ship   # the chosen policy as agents/policies/trained/…
    python scripts/results_pages.py       # the page docs/results/learners.md from the data

``train`` runs :func:`agents.training.learners.train_learner` once per learner × seed (tasks of a
runner:
here one after another, or on Ray) into ``RUNS/<learner>/seed_<k>/``; a finished run (its
``training.json`` exists) is skipped. ``evaluate`` flies every seed's exported policy beside the
anchors (``tuned_constant``, ``privileged``) and ``fis`` on the same test flights of every
scenario of the suite (``aeromag evaluate``'s path,
:func:`agents.evaluation.episodes.evaluate_scenarios`),
once, and writes to ``DATA``: ``flights.csv`` (one record per learner, seed, scenario and
flight: the RMSE), ``curves.csv`` (each validation point of each run: environment steps,
wall-clock seconds, the validation RMSE per scenario), ``runs.json`` (per run its minutes,
steps, validation score, hyperparameters) and ``policies/<learner>_seed<k>.npz`` (every seed's
exported policy). The test flights are fresh (seeds from ``--first-seed``, never flown for a
choice): versions were chosen on validation flights only.

``select`` chooses the policy to ship on validation flights only: every run's exported policy
flies the same ``--flights`` validation flights per scenario (the first of each scenario's
validation seeds; the training runs kept their checkpoint on 4 or 16 of them), scored as the
runs were (the worst scenario's mean RMSE ratio to the tuned constant); the learner with the
lowest mean score over its seeds wins, and of it the seed with the lowest score. Writes
``DATA/selection.json``; nothing of the test flights is read.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import shutil
import sys
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

if __package__ in (None, ""):  # run as a script: the checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.atomic import output_set, write_text
from aeromag_env.environment.ids import SUITE
from aeromag_env.parallel import Task, runner
from agents.training.learners import LEARNERS, train_learner

RUNS = Path("results/learners")
DATA = Path(__file__).resolve().parents[1] / "docs" / "learners"
#: The policies flown beside the learners on every test flight.
REFERENCES = ("tuned_constant", "privileged", "fis")
#: The first test flight's seed: fresh for this benchmark (earlier tables flew 100 000 on).
FIRST_SEED = 200_000


def seeds_arg(text: str) -> list[int]:
    """``0-4`` or ``0,2,5``."""
    if "-" in text:
        lo, hi = text.split("-", 1)
        return list(range(int(lo), int(hi) + 1))
    return [int(s) for s in text.split(",")]


def _train(learner: str, seed: int, folder: str) -> dict[str, Any]:
    out = Path(folder)
    done = out / "training.json"
    if done.exists():
        return json.loads(done.read_text())
    return train_learner(learner, seed, out)


def train(learners: Sequence[str], seeds: Sequence[int], runs: Path, ray: str | None) -> int:
    tasks = [  # seed by seed, so a run cut short has as many seeds of every learner
        Task(
            f"{learner} seed {seed}", _train, (learner, seed, str(runs / learner / f"seed_{seed}"))
        )
        for seed in seeds
        for learner in learners
    ]
    with runner(ray) as r:
        outcomes = r.run(tasks, lambda o: print(o.label, "ok" if o.ok else o.error, flush=True))
    return 0 if all(o.ok for o in outcomes) else 1


def _policies(runs: Path) -> dict[str, Path]:
    """``learner/seed`` → its exported policy, for every finished run under ``runs``."""
    found = {}
    for learner in LEARNERS:
        for folder in sorted((runs / learner).glob("seed_*")):
            if (folder / "policy.npz").exists() and (folder / "training.json").exists():
                found[f"{learner}/{folder.name.removeprefix('seed_')}"] = folder / "policy.npz"
    return found


def evaluate(runs: Path, episodes: int, first_seed: int, data: Path, ray: str | None) -> int:
    from agents.evaluation.episodes import evaluate_scenarios

    policies = _policies(runs)
    if not policies:
        print(f"no finished runs under {runs}", file=sys.stderr)
        return 2
    names = {key: f"ppo:{path}" for key, path in policies.items()}
    seeds = list(range(first_seed, first_seed + episodes))
    with runner(ray) as tasks:
        results = evaluate_scenarios(
            list(SUITE), [*REFERENCES, *names.values()], seeds, runner=tasks
        )
    flights = io.StringIO()
    w = csv.writer(flights, lineterminator="\n")
    w.writerow(["learner", "seed", "scenario", "flight", "rmse_nt"])
    for scenario, r in results.items():
        for ref in REFERENCES:
            for flight, v in zip(seeds, r["policies"][ref]["rmse_nt"], strict=True):
                w.writerow([ref, "", scenario, flight, repr(v)])
        for key, name in names.items():
            learner, seed = key.split("/")
            for flight, v in zip(seeds, r["policies"][name]["rmse_nt"], strict=True):
                w.writerow([learner, seed, scenario, flight, repr(v)])
    curves, runs_json = _curves(runs, policies)
    command = " ".join(["python -m experiments.compare_learners", *sys.argv[1:]])
    outputs = ("flights.csv", "curves.csv", "runs.json")
    with output_set(data, outputs) as stage:
        write_text(stage / "flights.csv", flights.getvalue())
        write_text(stage / "curves.csv", curves)
        meta = {
            "command": command,
            "date": datetime.now(UTC).strftime("%Y-%m-%d"),
            "test_flights": {"first_seed": first_seed, "per_scenario": episodes},
            "scenarios": list(SUITE),
            "validation_anchors": validation_anchors([r["validation_flights"] for r in runs_json]),
            "runs": runs_json,
        }
        write_text(stage / "runs.json", json.dumps(meta, indent=1))
    shelf = data / "policies"
    shelf.mkdir(parents=True, exist_ok=True)
    for key, path in policies.items():
        learner, seed = key.split("/")
        shutil.copyfile(path, shelf / f"{learner}_seed{seed}.npz")
    print(f"wrote {', '.join(str(data / o) for o in outputs)} and {len(policies)} policies")
    return 0


def _curves(runs: Path, policies: dict[str, Path]) -> tuple[str, list[dict[str, Any]]]:
    """The learning curves as CSV rows and each run's summary."""
    text = io.StringIO()
    w = csv.writer(text, lineterminator="\n")
    w.writerow(
        [
            "learner",
            "seed",
            "timesteps",
            "seconds",
            "train_seconds",
            "scenario",
            "flights",
            "validation_rmse_nt",
        ]
    )
    summaries = []
    for key, path in policies.items():
        learner, seed = key.split("/")
        summary = json.loads((path.parent / "training.json").read_text())
        curve = summary.get("curve") or json.loads((path.parent / "curve.json").read_text())
        per = _validation_flights(summary)
        for point in curve:
            seconds = round(point["seconds"], 2)
            train = round(point.get("train_seconds", point["seconds"]), 2)
            for scenario, v in point.get("validation_rmse_by_scenario", {}).items():
                w.writerow(
                    [learner, seed, point["timesteps"], seconds, train, scenario, per, repr(v)]
                )
        kept = min(curve, key=lambda p: p.get("validation_score", p["validation_rmse_nt"]))
        summaries.append(
            {
                "learner": learner,
                "seed": int(seed),
                "timesteps": summary["timesteps"],
                "minutes": round(summary["train_seconds_this_run"] / 60.0, 2),
                "validation_flights": _validation_flights(summary),
                "kept_timesteps": kept["timesteps"],
                "best_validation_score": summary.get("best_validation_score"),
                "hyperparams": summary.get("hyperparams"),
            }
        )
    return text.getvalue(), summaries


def _validation_flights(summary: dict[str, Any]) -> int:
    """Validation flights per scenario of a run (its ``eval_episodes`` split over the suite)."""
    return max(int(summary["hyperparams"]["eval_episodes"]) // len(SUITE), 1)


def validation_anchors(per_scenario: Sequence[int]) -> dict[str, dict[str, dict[str, float]]]:
    """The anchors' mean RMSE on the first ``n`` validation flights of each scenario, for each
    ``n`` of ``per_scenario``: what a learning curve's normalized score is measured against."""
    from agents.policies import policy_env_kwargs
    from agents.training.validation import validation_rmse

    return {
        str(n): {
            scenario: {
                ref: float(validation_rmse(ref, scenario, n, policy_env_kwargs(ref)).mean())
                for ref in ("tuned_constant", "privileged")
            }
            for scenario in SUITE
        }
        for n in sorted(set(per_scenario))
    }


def _validate(path: str, flights: int) -> dict[str, Any]:
    from agents.policies.numpy_policy import NumpyPolicy
    from agents.training.validation import Validator

    validator = Validator("worst_ratio_to_tuned_constant", "suite", flights * len(SUITE))
    return validator(NumpyPolicy.load(path))


def select(runs: Path, flights: int, data: Path, ray: str | None) -> int:
    # by its module's name, not __main__'s, so that a Ray worker can import it
    from experiments.compare_learners import _validate as validate

    policies = _policies(runs)
    tasks = [Task(key, validate, (str(path), flights)) for key, path in policies.items()]
    with runner(ray) as r:
        outcomes = r.run(tasks)
    failed = [o for o in outcomes if not o.ok]
    if failed:
        print(f"{failed[0].label}: {failed[0].error}", file=sys.stderr)
        return 1
    scored = {t.label: o.value for t, o in zip(tasks, outcomes, strict=True)}
    by_learner: dict[str, list[float]] = {}
    for key, point in scored.items():
        by_learner.setdefault(key.split("/")[0], []).append(point["validation_score"])
    means = {learner: sum(v) / len(v) for learner, v in by_learner.items()}
    best = min(means, key=means.__getitem__)
    seed = min(
        (k for k in scored if k.startswith(f"{best}/")),
        key=lambda k: scored[k]["validation_score"],
    )
    result = {
        "command": " ".join(["python -m experiments.compare_learners", *sys.argv[1:]]),
        "date": datetime.now(UTC).strftime("%Y-%m-%d"),
        "validation_flights_per_scenario": flights,
        "score": "worst scenario's mean RMSE ratio to tuned_constant (lower is better)",
        "runs": scored,
        "learner_mean_score": means,
        "chosen": {"learner": best, "seed": int(seed.split("/")[1])},
    }
    data.mkdir(parents=True, exist_ok=True)
    write_text(data / "selection.json", json.dumps(result, indent=1))
    for learner, mean in sorted(means.items(), key=lambda kv: kv[1]):
        print(f"{learner:15s} mean validation score {mean:.3f} over {len(by_learner[learner])}")
    print(f"chosen: {best} seed {result['chosen']['seed']}")
    return 0


def ship(runs: Path, data: Path, target: Path) -> int:
    """Write the policy ``select`` chose as the shipped general policy ``target``, its settings
    named by their preset (``general``) as the shipped files name theirs; unchanged when the
    arrays are already the shipped ones."""
    import numpy as np

    from aeromag_env.environment.config import PRESETS, env_config
    from agents.policies.policy_file import read_policy, write_policy

    chosen = json.loads((data / "selection.json").read_text())["chosen"]
    source = runs / chosen["learner"] / f"seed_{chosen['seed']}" / "policy.npz"
    arrays, meta = read_policy(source)
    if env_config(meta.get("env_kwargs", {})) != PRESETS["general"]:
        print(f"{source} was not trained with the general preset's settings", file=sys.stderr)
        return 2
    if target.exists():
        shipped, _ = read_policy(target)
        same = shipped.keys() == arrays.keys()
        if same and all(np.array_equal(shipped[k], arrays[k]) for k in arrays):
            print(f"{target} already holds {chosen['learner']} seed {chosen['seed']}'s policy")
            return 0
    meta = {**meta, "env_kwargs": {"preset": "general"}, "learner": chosen["learner"]}
    write_policy(arrays, meta, target)
    print(f"wrote {target}: {chosen['learner']} seed {chosen['seed']}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="step", required=True)
    t = sub.add_parser("train", help="train learners × seeds")
    t.add_argument("--learners", default=",".join(LEARNERS))
    t.add_argument("--seeds", default="0-4", type=seeds_arg)
    t.add_argument("--out", default=str(RUNS))
    e = sub.add_parser("evaluate", help="fly the test flights, write the data")
    e.add_argument("--runs", default=str(RUNS))
    e.add_argument("--episodes", type=int, default=30)
    e.add_argument("--first-seed", type=int, default=FIRST_SEED)
    e.add_argument("--data", default=str(DATA))
    c = sub.add_parser("select", help="choose the policy to ship, on validation flights")
    c.add_argument("--runs", default=str(RUNS))
    c.add_argument("--flights", type=int, default=8)
    c.add_argument("--data", default=str(DATA))
    for p in (t, e, c):
        p.add_argument("--ray", nargs="?", const="local", metavar="ADDRESS")
    h = sub.add_parser("ship", help="write the chosen policy as the shipped general policy")
    h.add_argument("--runs", default=str(RUNS))
    h.add_argument("--data", default=str(DATA))
    args = parser.parse_args(argv)
    if args.step == "train":
        learners = args.learners.split(",")
        unknown = [x for x in learners if x not in LEARNERS]
        if unknown:
            parser.error(f"unknown learners {', '.join(unknown)}; valid: {', '.join(LEARNERS)}")
        return train(learners, args.seeds, Path(args.out), args.ray)
    if args.step == "ship":
        from agents.policies import GENERAL_PPO

        return ship(Path(args.runs), Path(args.data), GENERAL_PPO)
    if args.step == "select":
        return select(Path(args.runs), args.flights, Path(args.data), args.ray)
    return evaluate(Path(args.runs), args.episodes, args.first_seed, Path(args.data), args.ray)


if __name__ == "__main__":
    raise SystemExit(main())
