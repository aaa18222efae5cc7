"""``aeromag discover`` over magnetic ground: what crustal geology hides.

Flies the hidden-effect suite's 30-min calibration-then-survey flight (box at 3000 m, lines at
400 m, :func:`aeromag_env.discovery.suite.base_config`) over simulated crustal geology
(:class:`aeromag_env.simulation.config.GeologyConfig`, defaults but the RMS):

* plain flights (nothing hidden), seeds 91000–91005, with 0, 10 and 50 nT of ground: what is
  named, the held-out gap, and whether the report's slow-residual caveat is raised;
* each single effect of the suite at SNR 2 (seeds 92000+) over 50 nT of ground: found or not.

Run: ``python -m experiments.discovery_geology`` (about 2 minutes); prints Markdown tables.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from aeromag_env.discovery.suite import SINGLE, Case, base_config, build_case
from aeromag_env.discovery.workflow import discover
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


def plain_flights() -> list[str]:
    rows = ["| ground [nT] | seed | named | held-out gap [nT] | caveat |", "|---|---|---|---|---|"]
    for rms in (0.0, 10.0, 50.0):
        for seed in range(91_000, 91_006):
            rep = discover(simulate_flight(_with_ground(base_config(1800.0), rms), seed)).report
            gap, caveat = rep["gap"], "yes" if rep["caveats"] else "no"
            rows.append(
                f"| {rms:g} | {seed} | {_named(rep)} | {gap['rms_before_nt']:.2f} → "
                f"{gap['rms_after_nt']:.2f} | {caveat} |"
            )
    return rows


def single_effects(rms_nt: float = 50.0, snr: float = 2.0) -> list[str]:
    rows = ["| effect (SNR 2, 50 nT ground) | named | caveat |", "|---|---|---|"]
    for k, name in enumerate(SINGLE):
        case = Case("single", 92_000 + k, (name,), snr)
        cfg, _ = build_case(case)
        rep = discover(simulate_flight(_with_ground(cfg, rms_nt), case.seed)).report
        rows.append(f"| `{name}` | {_named(rep)} | {'yes' if rep['caveats'] else 'no'} |")
    return rows


def main() -> None:
    print("\n".join([*plain_flights(), "", *single_effects()]))


if __name__ == "__main__":
    main()
