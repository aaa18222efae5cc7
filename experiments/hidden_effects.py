"""Hidden-effect suite for ``aeromag discover``: identification, false alarms, gap shrink.

Simulates every case of :func:`aeromag_env.discovery.suite.suite_cases` (null flights, coloured-
noise nulls, each identifiable effect at SNR 0.5/1/2/4, absorbed effects, pairs, and each effect
at SNR 0.1/0.25/0.5 on 20- to 60-min flights; decoy channels in every flight), runs the
discrepancy workflow on each and writes to ``--out`` (default ``results/discovery``; the
committed set is ``--out docs/discovery``) what
:func:`aeromag_env.discovery.power_report.write_suite` writes: ``results.json``,
``summary.json``, ``summary.md``, ``confusion.png``, ``power.png`` and ``power_duration.png``.

The defaults fly 1 140 flights: about 40 minutes on these 2-core machines (the committed set,
``--single 10 --null 40 --coloured 20 --absorbed 5 --pairs 5``, then ``--only duration
--durations 4``, took 10.3 and 17.5 minutes). ``--quick`` flies 9 cases (a minute or two).
``--only KIND... [--effects NAME...]`` re-runs the cases of those kinds (injecting one of those
effects; null flights always match) and replaces them in ``OUT/results.json``; ``--jobs 1``
runs in this process.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.discovery.power_report import in_subset, run_cases, write_suite
from aeromag_env.discovery.suite import Case, suite_cases
from aeromag_env.quick import add_quick_option


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--single", type=int, default=20, help="flights per effect and SNR")
    ap.add_argument("--null", type=int, default=60, help="null flights (nominal noise)")
    ap.add_argument("--coloured", type=int, default=20, help="coloured-noise null flights")
    ap.add_argument("--absorbed", type=int, default=10, help="flights per absorbed effect")
    ap.add_argument("--pairs", type=int, default=10, help="flights per pair")
    ap.add_argument("--durations", type=int, default=5, help="flights per effect, duration and SNR")
    ap.add_argument("--jobs", type=int, default=2, help="processes")
    ap.add_argument("--out", type=Path, default=Path("results/discovery"), help="output folder")
    add_quick_option(ap, "a handful of cases (about a minute)")
    ap.add_argument(
        "--only",
        nargs="+",
        metavar="KIND",
        help="run only these case kinds and replace them in OUT/results.json",
    )
    ap.add_argument(
        "--effects",
        nargs="+",
        metavar="NAME",
        help="with --only: only the cases injecting one of these effects (and the nulls)",
    )
    return ap


def main(argv: Sequence[str] | None = None) -> int:
    ap = _parser()
    args = ap.parse_args(argv)
    if args.effects and not args.only:
        ap.error("--effects needs --only (the subset replaces its cases in OUT/results.json)")
    sizes = (args.null, args.coloured, args.single, args.absorbed, args.pairs, args.durations)
    cases = suite_cases(*sizes) if not args.quick else _quick_cases()
    kept: list[dict] = []
    if args.only:
        cases = [c for c in cases if in_subset(c.kind, c.effects, args.only, args.effects)]
        previous = args.out / "results.json"
        if not previous.exists():
            ap.error(f"--only replaces cases in {previous}, which does not exist")
        old = json.loads(previous.read_text())
        kept = [r for r in old if not in_subset(r["kind"], r["effects"], args.only, args.effects)]
    t0 = time.perf_counter()

    def progress(k: int) -> None:
        if k % 50 == 0:
            print(f"{k}/{len(cases)} cases, {time.perf_counter() - t0:.0f} s", flush=True)

    rows = run_cases(cases, args.jobs, progress)
    ran = len(cases) if args.only else None
    print(write_suite(kept + rows, args.out, time.perf_counter() - t0, args.jobs, ran))
    print(f"wrote {args.out}")
    return 0


def _quick_cases() -> list[Case]:
    """``--quick``'s 9 cases: the first null and coloured-noise flights and the first flight
    of each effect at SNR 2 (every row the summary's tables need)."""
    cases = suite_cases(n_null=1, n_coloured=1, n_single=1, n_absorbed=0, n_pair=0)
    return [c for c in cases if c.kind != "single" or c.snr == 2.0]


if __name__ == "__main__":
    raise SystemExit(main())
