"""``aeromag discover`` over magnetic ground: what crustal geology hides.

Flies the hidden-effect suite's 30-min calibration-then-survey flight (box at 3000 m, lines at
400 m, :func:`aeromag_env.discovery.suite.base_config`) over simulated crustal geology
(:class:`aeromag_env.simulation.config.GeologyConfig`, defaults but the RMS):

* plain flights (nothing hidden), seeds 91000–91005, with 0, 10 and 50 nT of ground: what is
  named, the held-out gap, and whether the report's slow-residual caveat is raised;
* each single effect of the suite at SNR 2 (seeds 92000+) over 50 nT of ground: found or not.

Run: ``python experiments/discovery_geology.py [--quick]`` (25 flights, about 2 minutes on
these 2-core machines; ``--quick``: one plain flight over 0 and 50 nT and one effect, 3
flights); prints Markdown tables, writes nothing.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.discovery.suite import SINGLE, Case, base_config, build_case
from aeromag_env.discovery.workflow import discover
from aeromag_env.quick import add_quick_option
from aeromag_env.simulation.config import GeologyConfig, SimulationConfig
from aeromag_env.simulation.simulate import simulate_flight


def _with_ground(cfg: SimulationConfig, rms_nt: float) -> SimulationConfig:
    return cfg if rms_nt == 0 else dataclasses.replace(cfg, geology=GeologyConfig(rms_nt=rms_nt))


def _named(report: dict[str, Any]) -> str:
    found = [
        f"{e['name']}" + (f" ({e['channel']})" if e["channel"] else "")
        for e in report["missing_effects"]
    ]
    return ", ".join(found) or "–"


GROUND_NT = (0.0, 10.0, 50.0)
SEEDS = range(91_000, 91_006)


def plain_flights(
    ground_nt: Sequence[float] = GROUND_NT, seeds: Sequence[int] = SEEDS
) -> list[str]:
    rows = ["| ground [nT] | seed | named | held-out gap [nT] | caveat |", "|---|---|---|---|---|"]
    for rms in ground_nt:
        for seed in seeds:
            rep = discover(simulate_flight(_with_ground(base_config(1800.0), rms), seed)).report
            gap, caveat = rep["gap"], "yes" if rep["caveats"] else "no"
            rows.append(
                f"| {rms:g} | {seed} | {_named(rep)} | {gap['rms_before_nt']:.2f} → "
                f"{gap['rms_after_nt']:.2f} | {caveat} |"
            )
    return rows


def single_effects(
    rms_nt: float = 50.0, snr: float = 2.0, effects: Sequence[str] = SINGLE
) -> list[str]:
    rows = ["| effect (SNR 2, 50 nT ground) | named | caveat |", "|---|---|---|"]
    for k, name in enumerate(effects):
        case = Case("single", 92_000 + k, (name,), snr)
        cfg, _ = build_case(case)
        rep = discover(simulate_flight(_with_ground(cfg, rms_nt), case.seed)).report
        rows.append(f"| `{name}` | {_named(rep)} | {'yes' if rep['caveats'] else 'no'} |")
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    add_quick_option(parser, "3 flights")
    args = parser.parse_args(argv)
    if args.quick:
        tables = [*plain_flights((0.0, 50.0), SEEDS[:1]), "", *single_effects(effects=SINGLE[:1])]
    else:
        tables = [*plain_flights(), "", *single_effects()]
    print("\n".join(tables))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
