"""False alarms of ``aeromag discover`` on plain simulated flights.

Flies :func:`aeromag_env.discovery.plain_flights.plain_cases` (the ``nominal``, ``paper`` and
``noise_free`` presets in turn, 25 to 50 min, seeds 60000+), runs the workflow on each
(:func:`~aeromag_env.discovery.plain_flights.run_plain_flight`) and writes ``OUT/nominal.json``
(every flight's row) and ``OUT/nominal.md``
(:func:`~aeromag_env.discovery.plain_flights.plain_summary`). ``--out`` defaults to
``results/discovery``; the committed files are written by ``--out docs/discovery``.

The default 48 flights take about 3 minutes on these 2-core machines (the committed run's
workflow took 4.2 minutes over them on 2 processes; a rerun under a load of 16 took 11.9 minutes,
its workflow 5.3 times slower); ``--quick``, 4 flights, about a minute.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from multiprocessing import Pool
from pathlib import Path

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.atomic import output_set
from aeromag_env.discovery.plain_flights import plain_cases, plain_summary, run_plain_flight
from aeromag_env.quick import add_quick_option

#: ``--quick``'s flights: one round of the presets at the shortest duration.
QUICK_FLIGHTS = 4


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--flights", type=int, default=48, help="flights (presets in turn)")
    ap.add_argument("--jobs", type=int, default=2, help="processes (1: in this one)")
    ap.add_argument("--out", type=Path, default=Path("results/discovery"), help="output folder")
    add_quick_option(ap, f"{QUICK_FLIGHTS} flights")
    args = ap.parse_args(argv)
    cases = plain_cases(QUICK_FLIGHTS if args.quick else args.flights)
    t0 = time.perf_counter()
    if args.jobs == 1:
        rows = list(map(run_plain_flight, cases))
    else:
        with Pool(args.jobs) as pool:
            rows = pool.map(run_plain_flight, cases, chunksize=1)
    text = plain_summary(rows)
    with output_set(args.out, ("nominal.json", "nominal.md")) as stage:
        (stage / "nominal.json").write_text(json.dumps(rows, indent=1), encoding="utf-8")
        (stage / "nominal.md").write_text(text, encoding="utf-8")
    print(text)
    print(f"wrote {args.out}/nominal.json, nominal.md in {(time.perf_counter() - t0) / 60:.1f} min")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
