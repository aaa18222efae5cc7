"""Generate the documentation's results pages from the results files committed under ``docs/``.

Each page of ``docs/results/`` is made here from one or more committed results files, with the
command that wrote each file and the date of the commit that last changed it, so a page cannot
say a number its data does not hold (``tests/test_results_pages.py`` regenerates the pages and
compares them with the committed ones). Numbers whose results file is not committed are not on
these pages; the lab notebook keeps them as history.

Run from the checkout::

    python scripts/results_pages.py               # rewrite docs/results/*.md
    python scripts/results_pages.py --out DIR     # write them elsewhere (the test does)
    python scripts/results_pages.py --docs DIR    # read the results files from another docs/

The output depends only on the results files and their git history: no clock, no machine. A
page whose results files are not committed yet (:data:`PENDING`) is left out, and the index
names it among the results without a page. The learners' page and its figures are made in
``scripts/results_learners.py``; the helpers every page uses are in ``scripts/results_common.py``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

if __package__ in (None, ""):  # run as a script: the checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from results_common import GENERATOR, LEARNERS_DATA, num, pct, read, source_line, table

from aeromag_env.errors import AeromagError

ROOT = Path(__file__).resolve().parents[1]
SNRS = ("0.5", "1.0", "2.0", "4.0")


# --- the paper reproduced ---------------------------------------------------------------------


def _ours(value: Any) -> str:
    if value is None:
        return "never"
    if isinstance(value, list):
        if len(set(value)) == 1 and len(value) == 3:
            return f"{num(value[0])} nT per axis"
        return " vs ".join(num(v) for v in value)
    return num(value)


def _paper_claims(r: dict[str, Any]) -> list[tuple[str, ...]]:
    """The claims' rows of ``paper.md``: claim, criterion, ours, verdict."""
    return [
        (
            c["claim"],
            c["criterion"],
            _ours(c["ours"]),
            "reproduced" if c["reproduced"] else "**not reproduced**",
        )
        for c in r["claims"]
    ]


def _paper_filters(r: dict[str, Any]) -> list[tuple[str, ...]]:
    """The filters' rows of ``paper.md``: the fuzzy KF, the KF and the KF with the true R."""
    filters = {"fakf": r["fakf"], "kf": r["kf"], "kf with the true R": r["reference"]["kf_true_r"]}
    return [
        (
            f"`{name}`" if " " not in name else name,
            num(f["compensation_rmse_nt"]),
            num(f["ror_median"]),
            num(f["qoq_median"]),
            num(statistics.fmean(f["noise_std_est_nt"])),
            num(f["q_scale_final"]),
            num(f["r_scale_final"]),
            str(f["divergences"]),
        )
        for name, f in filters.items()
    ]


def paper_page(docs: Path) -> str:
    """``paper.md``: the paper's §4 claims judged on ``docs/paper/report.json``."""
    r = read(docs, "paper/report.json")
    s = r["setting"]
    claims, rows = _paper_claims(r), _paper_filters(r)
    n_ok = sum(c["reproduced"] for c in r["claims"] if not c["claim"].startswith("(not"))
    n_claims = sum(not c["claim"].startswith("(not") for c in r["claims"])
    lines = [
        "# The paper reproduced",
        "",
        source_line(docs, [("paper/report.json", f"aeromag reproduce-paper --seed {s['seed']}")]),
        "",
        "`aeromag reproduce-paper` flies the setting of the paper's §4 and judges each of its "
        "claims against a pass band fixed before the run. Why the claims that fail do so is in "
        "[the compensator and the paper](../background/compensator.md).",
        "",
        "## Setting",
        "",
        *table(
            ["seed", "duration [s]", "preset", "filter"],
            [(str(s["seed"]), num(s["duration_s"], 5), f"`{s['preset']}`", s["filter"])],
        ),
        "",
        "## The claims",
        "",
        f"{n_ok} of the paper's {n_claims} claims are reproduced.",
        "",
        *table(["claim", "criterion", "ours", "verdict"], claims),
        "",
        "## The filters",
        "",
        "Medians over the second half of the flight; RMSE of the estimated against the true "
        "interference [nT]; the final Q and R scales relative to the initial ones.",
        "",
        *table(
            [
                "filter",
                "RMSE [nT]",
                "ROR",
                "QOQ",
                "noise estimate [nT]",
                "Q scale",
                "R scale",
                "divergences",
            ],
            rows,
        ),
        "",
        "Batch least squares of the same 21 coefficients over the whole flight (the offline "
        f"optimum): RMSE {num(r['reference']['lsq_compensation_rmse_nt'])} nT.",
        "",
        "## Figures",
        "",
        "![The field along the flight](../paper/fig3_field.png)",
        "",
        "![The fuzzy adaptive filter's states](../paper/fig4_states.png)",
        "",
        "![Per-axis compensation and the ROR and QOQ statistics](../paper/fig5_compensation.png)",
    ]
    return "\n".join(lines) + "\n"


# --- the PPO tuners' training -----------------------------------------------------------------


def _flat(d: dict[str, Any], prefix: str = "") -> list[tuple[str, str]]:
    out: list[tuple[str, str]] = []
    for key, value in d.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out += _flat(value, f"{name}.")
        else:
            shown = json.dumps(value) if not isinstance(value, str) else value
            out.append((f"`{name}`", f"`{shown}`"))
    return out


def _training(docs: Path, name: str, title: str, scenario_note: str) -> list[str]:
    t = read(docs, name)
    hp = t["hyperparams"]
    steps = int(round(t["timesteps"], -5))
    command = f"aeromag train --scenario {t['scenario']} --timesteps {steps} --seed {t['seed']}"
    ratios = [sorted(p["validation_ratio"]) for p in t["curve"] if "validation_ratio" in p]
    scenarios = ratios[0] if ratios else []
    header = ["timesteps", "validation RMSE [nT]"]
    if "validation_score" in t["curve"][0]:
        header.append("worst ratio to `tuned_constant`")
    header += [f"`{s}`" for s in scenarios]
    rows = []
    for p in t["curve"]:
        row = [f"{p['timesteps']:,}", num(p["validation_rmse_nt"])]
        if "validation_score" in p:
            row.append(num(p["validation_score"]))
        row += [num(p["validation_ratio"][s]) for s in scenarios]
        rows.append(row)
    best = f"best validation RMSE {num(t['best_validation_rmse_nt'])} nT"
    if "best_validation_score" in t:
        best += f", best worst-scenario ratio {num(t['best_validation_score'])}"
    return [
        f"## {title}",
        "",
        source_line(docs, [(name, command)]),
        "",
        f"{scenario_note} Seed {t['seed']}, {t['timesteps']:,} steps in "
        f"{t['train_seconds_this_run'] / 60:.1f} min of training; {best}. The kept checkpoint "
        "is the shipped policy.",
        "",
        "### Validation during training",
        "",
        *table(header, rows),
        "",
        "### Hyperparameters",
        "",
        *table(["key", "value"], _flat(hp)),
        "",
    ]


def tuners_page(docs: Path) -> str:
    """``tuners.md``: the training records of the two shipped PPO policies."""
    lines = [
        "# The PPO tuners' training",
        "",
        "The records of the training runs of the two shipped PPO policies: the validation curve "
        "(RMSE on validation flights, seeds 50 000–99 999, never test flights) and the "
        "hyperparameters. How to train your own: "
        "[training and evaluating tuners](../howto/train-and-evaluate.md); what the scores mean: "
        "[benchmark methodology](../background/benchmark-methodology.md).",
        "",
        *_training(
            docs,
            "ppo/training.json",
            "`ppo`: the `nonstationary` tuner",
            "Trained on `nonstationary_dense`, validated on `nonstationary` "
            "(`agents/policies/trained/ppo_nonstationary.npz`).",
        ),
        "![Learning curve of the nonstationary tuner](../ppo/learning_curve.png)",
        "",
        *_training(
            docs,
            "general/training.json",
            "`general`: one policy for the suite",
            "Trained and validated on flights of every scenario of the suite "
            "(`agents/policies/trained/ppo_general.npz`); the ratios are each scenario's mean "
            "validation RMSE over the tuned constant's on the same flights.",
        ),
        "## Not on this page",
        "",
        "The benchmark of every policy on every scenario's test flights (RMSE, paired intervals, "
        "normalized scores, the IQM over training seeds) has no committed results file; its "
        "last runs are in the lab notebook: "
        "[the evaluation runs](../lab-notebook/evaluation-runs.md) and "
        "[the general policy](../lab-notebook/general-policy.md).",
    ]
    return "\n".join(lines) + "\n"


# --- discovery power and false alarms ---------------------------------------------------------


def _clopper_pearson(k: int, n: int) -> tuple[float, float]:
    from scipy.stats import beta

    low = 0.0 if k == 0 else float(beta.ppf(0.025, k, n - k + 1))
    high = 1.0 if k == n else float(beta.ppf(0.975, k + 1, n - k))
    return low, high


def _nominal(flights: list[dict[str, Any]]) -> list[str]:
    n = len(flights)
    presets: dict[str, int] = {}
    for f in flights:
        presets[f["preset"]] = presets.get(f["preset"], 0) + 1
    alarms = sum(bool(f["false_alarm"]) for f in flights)
    low, high = _clopper_pearson(alarms, n)
    named = sum(bool(f["named"]) for f in flights)
    per_hour = statistics.median(f["seconds"] / (f["duration_s"] / 3600) for f in flights)
    nominal = [f for f in flights if f["preset"] == "nominal"]
    shrink = [
        f["gap_before_nt"] / f["gap_after_nt"]
        for f in nominal
        if f["named"] and f["gap_after_nt"] and f["gap_after_nt"] > 0
    ]
    by = ", ".join(f"{k} {v}" for k, v in presets.items())
    lines = [
        f"* flights: {n} ({by})",
        f"* false alarms (an effect the flight does not carry): {alarms}/{n} "
        f"(95 % CI {100 * low:.0f}–{100 * high:.0f} %)",
        f"* any effect named: {named}/{n}",
        f"* discover: median {per_hour:.1f} s per flight-hour (workflow only, no figures)",
    ]
    if shrink:
        lines.append(
            f"* nominal flights that named an effect: held-out gap {min(shrink):.1f}–"
            f"{max(shrink):.1f}× smaller with it"
        )
    return lines


def _discovery_claims(s: dict[str, Any]) -> list[tuple[str, str, str]]:
    """The claims' rows of ``discovery.md``: claim, target, result."""
    one, fa = s["single_snr_ge_2"], s["false_alarm"]
    return [
        ("single effects at SNR ≥ 2, exact set named", "≥ 90 %", pct(one["exact_set"])),
        ("single effects at SNR ≥ 2, first named = truth", "–", pct(one["top1"])),
        ("false alarms on null flights (nominal + coloured noise)", "≤ 5 %", pct(fa["all_nulls"])),
        ("… coloured-noise nulls only", "–", pct(fa["coloured_null"])),
        ("absorbed effects named", "0", str(s["absorbed"]["absorbed_effect_named"])),
        (
            f"decoy channels named (all {s['cases_with_decoys']} flights)",
            "0",
            str(s["decoy_named"]),
        ),
        (
            "held-out gap shrink at SNR ≥ 2, median",
            "≥ 2×",
            f"{one['median_shrink']:.2f}× (≥ 2× in {pct(one['shrink_at_least_2'])})",
        ),
        ("pairs at SNR 4, exact set", "–", pct(s["pairs_exact_set"])),
    ]


def _discovery_duration(d: dict[str, Any]) -> list[str]:
    """The power-against-duration section's lines of ``discovery.md`` (its tables)."""
    lines = [
        f"{d['flights']} flights; detected = {d['detection']}; decoy channels named on these "
        f"flights: {d['decoy_named']}.",
        "",
    ]
    for snr, per in d["power"].items():
        durations = list(next(iter(per.values())))
        lines += table(
            [f"effect (SNR {snr})", *(f"{int(x) // 60} min" for x in durations)],
            [(f"`{name}`", *(pct(per[name][x]) for x in durations)) for name in per],
        )
        lines.append("")
    return lines


def _discovery_effects(s: dict[str, Any]) -> list[tuple[str, ...]]:
    """The per-effect rows of ``discovery.md``: exact set, gap shrink, power by SNR."""
    return [
        (
            f"`{name}`",
            f"{100 * e['exact']['rate']:.0f} %",
            f"{e['median_shrink']:.1f}×",
            " / ".join(f"{100 * s['power'][name][x]['rate']:.0f} %" for x in SNRS),
        )
        for name, e in s["single_snr_ge_2"]["per_effect"].items()
    ]


def _discovery_confusion(conf: dict[str, dict[str, int]]) -> list[str]:
    """The confusion table's lines of ``discovery.md``: injected effects by what was named."""
    cols = list(next(iter(conf.values())))
    rows = [(f"`{t}`", *(str(conf[t][c]) for c in cols)) for t in conf]
    return table(["injected", *(f"`{c}`" for c in cols)], rows)


def _discovery_sources(docs: Path) -> str:
    """The source line of ``discovery.md``: its data files and the commands that wrote them."""
    return source_line(
        docs,
        [
            (
                "discovery/summary.json",
                "python -m experiments.hidden_effects --single 10 --null 40 --coloured 20 "
                "--absorbed 5 --pairs 5 --out docs/discovery (10.3 min on a 2-core machine), "
                "then --only duration --durations 4 --out docs/discovery (17.5 min)",
            ),
            (
                "discovery/nominal.json",
                "python -m experiments.discovery_nominal --out docs/discovery",
            ),
        ],
    )


def discovery_page(docs: Path) -> str:
    """``discovery.md``: the hidden-effect suite and the plain-flight false alarms."""
    s = read(docs, "discovery/summary.json")
    claims, effects = _discovery_claims(s), _discovery_effects(s)
    cases = ", ".join(f"{k} {v}" for k, v in s["cases"].items())
    lines = [
        "# Discovery power and false alarms",
        "",
        _discovery_sources(docs),
        "",
        "The hidden-effect suite injects known effects into simulated flights and asks "
        "`aeromag discover` to name them; decoy channels ride along in every flight. Strength "
        "is the identifiable SNR (the RMS of the injected field outside the base model's span "
        "over the noise std). The method: [the discovery statistics](../background/discovery.md).",
        "",
        f"Cases: {cases}.",
        "",
        "## Claims",
        "",
        *table(["claim", "target", "result"], claims),
        "",
        "## Per effect",
        "",
        *table(
            [
                "effect (SNR ≥ 2)",
                "exact set",
                "median gap shrink",
                "power at SNR 0.5 / 1 / 2 / 4",
            ],
            effects,
        ),
        "",
        "![Confusion of the named effects](../discovery/confusion.png) "
        "![Power against SNR](../discovery/power.png)",
        "",
        "## Confusion",
        "",
        "Rows: the injected effect (single effects at SNR ≥ 2, and null flights); columns: what "
        "was named.",
        "",
        *_discovery_confusion(s["confusion"]),
        "",
        "## Power against flight duration",
        "",
        *_discovery_duration(s["power_duration"]),
        "![Power against flight duration](../discovery/power_duration.png)",
        "",
        "## Plain simulated flights",
        "",
        "Flights of the presets as `aeromag simulate --pattern calibration+survey` makes them, "
        "with nothing injected. A `nominal` flight carries an external field variation its "
        "`diurnal` channel records only along the main field; naming it is no false alarm.",
        "",
        *_nominal(read(docs, "discovery/nominal.json")),
    ]
    return "\n".join(lines) + "\n"


# --- the learners for the general tuner --------------------------------------------------------


def learners_page(docs: Path) -> str:
    """``learners.md``, made in ``scripts/results_learners.py`` (imported only when its data are
    there: it imports ``agents``)."""
    import results_learners

    return results_learners.learners_page(docs)


def learners_files(docs: Path) -> dict[str, str | bytes]:
    """The figures and the table beside ``learners.md``."""
    import results_learners

    return results_learners.learners_files(docs)


def index_page(docs: Path) -> str:
    """``index.md``: what the results pages are and which results are not among them."""
    lines = [
        "# Results",
        "",
        f"Each page here is generated by `{GENERATOR}` from results files committed under "
        "`docs/`, and names the command that wrote each file and the date it was last "
        "committed; `tests/test_results_pages.py` fails when a page and its data disagree.",
        "",
        *(
            f"* [{title}]({name})"
            for name, (title, _) in PAGES.items()
            if name != "index.md" and available(docs, name)
        ),
        "",
        "Not generated, because their raw results files are not committed: the evaluation of "
        "every policy on every scenario, the general policy over training seeds, the method "
        "comparison and the speed benchmarks. Their last runs are in the "
        "[lab notebook](../lab-notebook/index.md).",
    ]
    if not available(docs, "learners.md"):
        lines += [
            "",
            "The comparison of the learners for the general tuner gets its page when its data, "
            "`docs/learners/` (`python -m experiments.compare_learners evaluate --data "
            "docs/learners`), are committed.",
        ]
    return "\n".join(lines) + "\n"


PAGES: dict[str, tuple[str, Callable[[Path], str]]] = {
    "index.md": ("Results", index_page),
    "paper.md": ("The paper reproduced", paper_page),
    "tuners.md": ("The PPO tuners' training", tuners_page),
    "discovery.md": ("Discovery power and false alarms", discovery_page),
    "learners.md": ("Learners for the general tuner", learners_page),
}
#: Pages made only once their results files are committed; until then the index names them
#: among the results without a page.
PENDING: dict[str, tuple[str, ...]] = {"learners.md": LEARNERS_DATA}
#: The files a page shows beside it (figures, tables), made from the same results files.
FILES: dict[str, Callable[[Path], dict[str, str | bytes]]] = {"learners.md": learners_files}


def available(docs: Path, page: str) -> bool:
    """Whether ``page``'s results files are under ``docs`` (always, but for :data:`PENDING`
    pages); a one-line error when only some of a pending page's files are there."""
    files = PENDING.get(page, ())
    present = [f for f in files if (docs / f).exists()]
    if present and len(present) < len(files):
        absent = ", ".join(f"docs/{f}" for f in files if f not in present)
        raise FileNotFoundError(f"{page} needs {absent} beside {', '.join(present)}")
    return len(present) == len(files)


def generate(docs: Path) -> dict[str, str | bytes]:
    """Every results page and the files beside them, by file name, from the results files
    under ``docs``."""
    out: dict[str, str | bytes] = {}
    for name, (_, make) in PAGES.items():
        if available(docs, name):
            out[name] = make(docs)
            if name in FILES:
                out.update(FILES[name](docs))
    return out


def main(argv: list[str] | None = None) -> int:
    """Write the results pages; exit status 0, 2 (with a one-line message) when a results file
    is missing or does not hold what its page needs."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--docs", type=Path, default=ROOT / "docs", help="folder of results files")
    parser.add_argument("--out", type=Path, help="output folder (default DOCS/results)")
    args = parser.parse_args(argv)
    out = args.out or args.docs / "results"
    try:
        files = generate(args.docs)
    except (OSError, ValueError, AeromagError) as e:
        print(f"results_pages: {e}", file=sys.stderr)
        return 2
    except KeyError as e:
        print(f"results_pages: a results file lacks the key {e}", file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    for name, content in files.items():
        if isinstance(content, bytes):
            (out / name).write_bytes(content)
        else:
            (out / name).write_text(content)
    return 0


if __name__ == "__main__":
    sys.exit(main())
