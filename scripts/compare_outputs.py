"""Compare two captures of ``scripts/capture-outputs``: the same demo tables and summary, the
same ``results.json`` per scenario, the same ``report.json`` per method and the same printed
walkthrough (each capture's own folder read as ``OUT``; timing lines left out).

Usage: ``python scripts/compare_outputs.py BEFORE AFTER`` (exit 1 when anything differs).
"""

from __future__ import annotations

import re
import sys
from pathlib import Path


def _text(path: Path, root: Path, drop: str | None) -> str:
    lines = path.read_text(encoding="utf-8").replace(str(root), "OUT").splitlines()
    return "\n".join(line for line in lines if not (drop and re.search(drop, line)))


def main(argv: list[str]) -> int:
    before, after = (Path(a).resolve() for a in argv)
    sets = sorted([*before.glob("evaluate/*/results.json"), *before.glob("own/*/report.json")])
    checks = [
        ("demo.txt", r"took|seconds|elapsed"),
        ("demo/summary.json", None),
        *((str(p.relative_to(before)), None) for p in sets),
        ("own.txt", None),
    ]
    differ = 0
    for name, drop in checks:
        if not (after / name).exists():
            print(f"missing {name}")
            differ += 1
            continue
        same = _text(before / name, before, drop) == _text(after / name, after, drop)
        print(("same " if same else "DIFF ") + name)
        differ += not same
    print(f"{differ} of {len(checks)} differ")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
