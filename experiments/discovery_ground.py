"""``aeromag discover --ground separate`` against ``ignore`` over simulated magnetic ground.

The suite's 30-min calibration-then-survey flight (box at 3000 m, lines at 400 m,
:func:`aeromag_env.discovery.suite.base_config`) over crustal geology
(:class:`aeromag_env.simulation.config.GeologyConfig`, defaults but the RMS, a new ground per
seed), with seeds no choice of the ground separation was made on (96000+, 97000+):

* plain flights (nothing hidden), 20 per ground level (0, 10, 50, 200 nT at 400 m): how many
  name anything (false alarms, with a Clopper–Pearson 95 % interval), the median held-out gap;
* each single effect of the suite at SNR 2, 5 flights per effect and ground level (50, 200
  nT): how many are found, and, when not, whether the report says the ground absorbs it.

``--low`` flies the lines at 150 m instead (ground over a 30-km area, seeds 98000+): 4 plain
flights and 4 each with ``eddy_time_constant`` and ``induced_second_order`` at SNR 2, per
ground level (50, 200 nT at 400 m), ``separate`` only.

Run: ``python experiments/discovery_ground.py [--low] [--quick]`` (about 10 minutes on these
2-core machines; ``--low`` 1 minute; ``--quick``: one plain flight over 0 and 50 nT and one
effect over 50 nT, or with ``--low`` one plain and one effect flight); prints Markdown, writes
nothing.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from statistics import median
from typing import Any

from scipy.stats import beta

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.discovery.suite import SINGLE, Case, base_config, build_case
from aeromag_env.discovery.workflow import discover
from aeromag_env.quick import add_quick_option
from aeromag_env.simulation.config import GeologyConfig, SimulationConfig
from aeromag_env.simulation.simulate import simulate_flight

MODES = ("ignore", "separate")
PLAIN_GROUND_NT = (0.0, 10.0, 50.0, 200.0)
EFFECT_GROUND_NT = (50.0, 200.0)
N_PLAIN, N_EFFECT = 20, 5


def _config(cfg: SimulationConfig, rms_nt: float) -> SimulationConfig:
    return cfg if rms_nt == 0 else dataclasses.replace(cfg, geology=GeologyConfig(rms_nt=rms_nt))


LOW_ALTITUDE_M = 150.0
LOW_EFFECTS = ("plain", "eddy_time_constant", "induced_second_order")


def _low(cfg: SimulationConfig, rms_nt: float) -> SimulationConfig:
    """``cfg`` with its lines at :data:`LOW_ALTITUDE_M`, over ground of ``rms_nt`` (at 400 m)."""
    survey = dataclasses.replace(cfg.trajectory.survey, altitude_m=LOW_ALTITUDE_M)
    geology = GeologyConfig(rms_nt=rms_nt, min_altitude_m=140.0, area_size_km=30.0)
    trajectory = dataclasses.replace(cfg.trajectory, survey=survey)
    return dataclasses.replace(cfg, trajectory=trajectory, geology=geology)


def _run_low(job: tuple[str, int, float]) -> list[str]:
    """One low flight, ``separate``: a table row."""
    name, seed, rms_nt = job
    cfg = (
        base_config(1800.0)
        if name == "plain"
        else build_case(Case("single", seed, (name,), 2.0))[0]
    )
    rep = discover(simulate_flight(_low(cfg, rms_nt), seed), ground="separate").report
    named = ", ".join(e["name"] for e in rep["missing_effects"]) or "–"
    return [name, str(seed), f"{rms_nt:g}", named, f"{rep['gap']['rms_before_nt']:.2f}"]


def low_table(
    ground_nt: Sequence[float] = EFFECT_GROUND_NT,
    effects: Sequence[str] = LOW_EFFECTS,
    flights: int = 4,
) -> list[str]:
    jobs = [
        (name, 98_000 + k, rms) for rms in ground_nt for name in effects for k in range(flights)
    ]
    with ProcessPoolExecutor(2) as pool:
        rows = list(pool.map(_run_low, jobs))
    head = [
        "| hidden (SNR 2), lines at 150 m | seed | ground [nT] | named | held-out gap [nT] |",
        "|---|---|---|---|---|",
    ]
    return head + [f"| {' | '.join(r)} |" for r in rows]


def _run(job: tuple[str, int, float, float]) -> dict[str, Any]:
    """One flight, both modes: what each names, its gap, and what the ground absorbs."""
    name, seed, rms_nt, snr = job
    cfg = (
        base_config(1800.0)
        if name == "plain"
        else build_case(Case("single", seed, (name,), snr))[0]
    )
    flight = simulate_flight(_config(cfg, rms_nt), seed)
    out: dict[str, Any] = {"name": name, "seed": seed, "ground_nt": rms_nt}
    for mode in MODES:
        rep = discover(flight, ground=mode).report
        absorbed = {
            c["name"]
            for c in rep["candidates"]
            if c["verdict"] == "absorbed" and "ground" in str(c.get("absorbed_by"))
        }
        out[mode] = {
            "named": [e["name"] for e in rep["missing_effects"]],
            "gap": rep["gap"]["rms_before_nt"],
            "absorbed": sorted(absorbed),
        }
    return out


def _interval(k: int, n: int) -> str:
    lo = beta.ppf(0.025, k, n - k + 1) if k else 0.0
    hi = beta.ppf(0.975, k + 1, n - k) if k < n else 1.0
    return f"{k}/{n} ({100 * lo:.0f}–{100 * hi:.0f} %)"


def plain_table(rows: list[dict[str, Any]], ground_nt: Sequence[float]) -> list[str]:
    out = [
        "| ground [nT] | flights naming anything: ignore | separate | median held-out gap "
        "[nT]: ignore | separate |",
        "|---|---|---|---|---|",
    ]
    for rms in ground_nt:
        sub = [r for r in rows if r["name"] == "plain" and r["ground_nt"] == rms]
        cells = [_interval(sum(bool(r[m]["named"]) for r in sub), len(sub)) for m in MODES]
        gaps = [f"{median(r[m]['gap'] for r in sub):.2f}" for m in MODES]
        out.append(f"| {rms:g} | {' | '.join(cells)} | {' | '.join(gaps)} |")
    return out


def effect_table(
    rows: list[dict[str, Any]], effects: Sequence[str], ground_nt: Sequence[float]
) -> list[str]:
    out = [
        "| effect (SNR 2) | ground [nT] | found: ignore | separate | separate: absorbed by "
        "the ground (said so) |",
        "|---|---|---|---|---|",
    ]
    for name in effects:
        for rms in ground_nt:
            sub = [r for r in rows if r["name"] == name and r["ground_nt"] == rms]
            found = [sum(name in r[m]["named"] for r in sub) for m in MODES]
            said = sum(name in r["separate"]["absorbed"] for r in sub)
            out.append(
                f"| `{name}` | {rms:g} | {found[0]}/{len(sub)} | {found[1]}/{len(sub)} | "
                f"{said}/{len(sub)} |"
            )
    return out


@dataclass(frozen=True, kw_only=True)
class Sizes:
    """Flights per ground level (plain) and per effect and ground level, and which."""

    plain: int = N_PLAIN
    per_effect: int = N_EFFECT
    plain_ground_nt: tuple[float, ...] = PLAIN_GROUND_NT
    effect_ground_nt: tuple[float, ...] = EFFECT_GROUND_NT
    effects: tuple[str, ...] = SINGLE


#: ``--quick``'s flights: one plain over 0 and 50 nT, one of the first effect over 50 nT.
QUICK = Sizes(
    plain=1, per_effect=1, plain_ground_nt=(0.0, 50.0), effect_ground_nt=(50.0,), effects=SINGLE[:1]
)


def jobs(sizes: Sizes) -> list[tuple[str, int, float, float]]:
    """The flights ``(effect or "plain", seed, ground RMS [nT], SNR)`` of ``sizes``; a flight's
    seed depends only on its ground level's and effect's places in the full lists."""
    plain = [
        ("plain", 96_000 + 100 * PLAIN_GROUND_NT.index(rms) + i, rms, 0.0)
        for rms in sizes.plain_ground_nt
        for i in range(sizes.plain)
    ]
    effects = [
        (name, 97_000 + 1000 * EFFECT_GROUND_NT.index(rms) + 10 * SINGLE.index(name) + i, rms, 2.0)
        for rms in sizes.effect_ground_nt
        for name in sizes.effects
        for i in range(sizes.per_effect)
    ]
    return plain + effects


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--low", action="store_true", help="lines at 150 m, separate only")
    add_quick_option(parser, "3 flights (2 with --low)")
    args = parser.parse_args(argv)
    if args.low:
        low = low_table((50.0,), LOW_EFFECTS[:2], 1) if args.quick else low_table()
        print("\n".join(low))
        return 0
    sizes = QUICK if args.quick else Sizes()
    with ProcessPoolExecutor(2) as pool:
        rows = list(pool.map(_run, jobs(sizes)))
    plain = plain_table(rows, sizes.plain_ground_nt)
    print("\n".join([*plain, "", *effect_table(rows, sizes.effects, sizes.effect_ground_nt)]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
