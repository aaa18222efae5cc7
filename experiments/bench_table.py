"""The README's Performance table from several ``aeromag bench`` runs, side by side.

Each ``bench.json`` holds one run's medians and the ratios measured in that run; this script
puts the runs next to each other (``a / b / c``) and counts in how many runs each target was
met. It measures nothing itself.

Run: ``python experiments/bench_table.py results/bench_1/bench.json results/bench_2/bench.json …``
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.jobs.bench.table import rows as table_rows

#: A number in a cell (sign, thousands separators, decimals), or a range of two ("1.11–1.33",
#: "-5.5–59.2": a paired difference may come out negative on a noisy machine).
_NUMBER = re.compile(r"-?[0-9][0-9,]*(?:\.[0-9]+)?(?:–-?[0-9][0-9,]*(?:\.[0-9]+)?)?")


def load_runs(paths: Sequence[Path]) -> list[dict[str, Any]]:
    """The runs' ``bench.json`` contents; a one-line error for a missing or foreign file."""
    runs = []
    for path in paths:
        try:
            run = json.loads(Path(path).read_text())
        except (OSError, json.JSONDecodeError) as e:
            raise SystemExit(f"cannot read {path}: {e}") from None
        if not isinstance(run, dict) or "figures" not in run:
            raise SystemExit(f"{path} is not an aeromag bench.json (no 'figures')")
        runs.append(run)
    return runs


def join_cells(cells: Sequence[str]) -> str:
    """The runs' cells as one: where they share their words and differ only in numbers, each
    number slot lists the runs' values (``"1.2× x", "1.3× x"`` → ``"1.2 / 1.3× x"``; a slot
    equal in all runs once); otherwise every run's cell in full, separated by ``<br>``."""
    templates = {_NUMBER.sub("#", c) for c in cells}
    if len(templates) != 1:
        return "<br>".join(cells)
    slots = zip(*(_NUMBER.findall(c) for c in cells), strict=True)
    values = [v[0] if len(set(v)) == 1 else " / ".join(v) for v in slots]
    pieces = templates.pop().split("#")
    return pieces[0] + "".join(v + p for v, p in zip(values, pieces[1:], strict=True))


def table(runs: Sequence[dict[str, Any]]) -> str:
    """A Markdown table: benchmark, the runs' medians, their ratios, target (met in k of n)."""
    per_run = [{r[0]: r for r in table_rows(run["figures"])} for run in runs]
    names = [name for name in per_run[0] if all(name in rows for rows in per_run)]
    lines = [
        "| benchmark | median, "
        + " / ".join(f"run {i + 1}" for i in range(len(runs)))
        + " | ratio to the reference, same run | target |",
        "|---|---|---|---|",
    ]
    for name in names:
        rows = [rows[name] for rows in per_run]
        target, met = rows[0][3], [r[4] for r in rows]
        verdict = "" if met[0] is None else f"{target}: met in {sum(met)} of {len(met)}"
        lines.append(
            f"| {name} | {join_cells([r[1] for r in rows])} | "
            f"{join_cells([r[2] for r in rows])} | {verdict} |"
        )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("bench_json", nargs="+", type=Path, help="bench.json files, in order")
    args = parser.parse_args(argv)
    runs = load_runs(args.bench_json)
    print(table(runs))
    for i, run in enumerate(runs, 1):
        load, machine = run.get("load_average_1min", {}), run.get("machine", {})
        print(
            f"\nrun {i}: {machine.get('processor')}, {machine.get('cpus')} cores, Python "
            f"{machine.get('python')}, numpy {machine.get('numpy')}, numba "
            f"{machine.get('numba')}; load average {_two(load.get('before'))} before, "
            f"{_two(load.get('after'))} after; {run.get('repeats')} repeats "
            f"({run.get('ppo_repeats')} for PPO)"
        )
    return 0


def _two(value: float | None) -> str:
    return "?" if value is None else f"{value:.2f}"


if __name__ == "__main__":
    raise SystemExit(main())
