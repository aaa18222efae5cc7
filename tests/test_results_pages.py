"""The results pages under ``docs/results/`` are what ``scripts/results_pages.py`` makes from the
committed results files: regenerating them gives the committed pages, and a changed number in a
results file changes its page. The learners' page is checked on synthetic data in the format of
``experiments/compare_learners.py evaluate`` whose verdicts are known by construction.

The script runs in a subprocess (tests import nothing from ``scripts/`` or ``experiments/``).
"""

from __future__ import annotations

import csv
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from aeromag_env.environment.ids import SUITE

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "scripts" / "results_pages.py"
RESULTS = ROOT / "docs" / "results"
#: What is compared with the committed files: the pages and the tables beside them. Not the
#: figures: their pixels follow the installed matplotlib and FreeType, not only the data.
COMPARED = ("*.md", "*.csv")


def run(out: Path, docs: Path = ROOT / "docs") -> subprocess.CompletedProcess[str]:
    """Run the generator into ``out``."""
    return subprocess.run(
        [sys.executable, str(SCRIPT), "--docs", str(docs), "--out", str(out)],
        check=False,
        capture_output=True,
        text=True,
    )


def generate(out: Path, docs: Path = ROOT / "docs") -> dict[str, str]:
    """Run the generator into ``out``; the pages and tables it wrote, by name."""
    done = run(out, docs)
    assert done.returncode == 0, done.stderr[-3000:]
    return {p.name: p.read_text() for pattern in COMPARED for p in sorted(out.glob(pattern))}


def shallow() -> bool:
    """A shallow clone: the dates of the results files' last commits are unknown."""
    run = subprocess.run(
        ["git", "rev-parse", "--is-shallow-repository"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
    )
    return run.stdout.strip() != "false"


def test_regenerating_gives_the_committed_pages(tmp_path: Path) -> None:
    if shallow():
        pytest.skip("not a full git checkout: the pages' dates come from the git history")
    fresh = generate(tmp_path)
    committed = {p.name: p.read_text() for pattern in COMPARED for p in RESULTS.glob(pattern)}
    assert sorted(fresh) == sorted(committed), "docs/results holds pages the script does not make"
    for name, text in fresh.items():
        assert committed[name] == text, (
            f"docs/results/{name} differs from what its results files give: "
            "run python scripts/results_pages.py and commit the pages"
        )


def test_a_changed_number_in_a_results_file_changes_its_page(tmp_path: Path) -> None:
    docs = tmp_path / "docs"
    for folder in ("paper", "ppo", "general", "discovery"):
        shutil.copytree(ROOT / "docs" / folder, docs / folder)
    report = json.loads((docs / "paper" / "report.json").read_text())
    report["fakf"]["compensation_rmse_nt"] = 123.456
    report["claims"][0]["reproduced"] = not report["claims"][0]["reproduced"]
    (docs / "paper" / "report.json").write_text(json.dumps(report))
    pages = generate(tmp_path / "out", docs)
    assert "| `fakf` | 123 |" in pages["paper.md"]
    assert "not committed" in pages["paper.md"]  # a copy outside git has no commit date
    before = (RESULTS / "paper.md").read_text()
    assert before.count("**not reproduced**") != pages["paper.md"].count("**not reproduced**")


# --- the learners' page on synthetic data --------------------------------------------------------

FLIGHTS = 10
FIRST = 200_000
#: The scenario where privileged is no better than tuned_constant: not scored.
FLAT = "manoeuvre_heavy"


def _learners_rmse(rng: np.random.Generator) -> dict[tuple[str, str], np.ndarray]:
    """RMSE ``(scenarios, flights)`` [nT] per (policy, seed): ``ppo`` near privileged (meets the
    bar), ``sac`` too but seed 3 worse than tuned_constant on ``noise_bursts``, ``cmaes`` the
    tuned constant itself (meets all but the IQM), ``recurrent_ppo`` (4 seeds) between."""
    base = rng.uniform(1.0, 5.0, (len(SUITE), FLIGHTS))
    tc = base + 1.0 + rng.normal(0, 0.1, base.shape)
    privileged = base.copy()
    privileged[SUITE.index(FLAT)] = tc[SUITE.index(FLAT)] + 0.3
    out = {("tuned_constant", ""): tc, ("privileged", ""): privileged, ("fis", ""): base + 2.0}
    for seed in range(5):
        out["ppo", str(seed)] = base + 0.1 + rng.normal(0, 0.05, base.shape)
        sac = base + 0.2 + rng.normal(0, 0.05, base.shape)
        if seed == 3:
            sac[SUITE.index("noise_bursts")] = tc[SUITE.index("noise_bursts")] + 0.5
        out["sac", str(seed)] = sac
        out["cmaes", str(seed)] = tc
        if seed < 4:
            out["recurrent_ppo", str(seed)] = base + 0.6 + rng.normal(0, 0.05, base.shape)
    return out


def _write_csv(path: Path, header: list[str], rows: list[list[object]]) -> None:
    with path.open("w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(header)
        w.writerows(rows)


#: The validation score of each learner's k-th point (every seed): known curves.
CURVE = {"ppo": [0.2, 0.5, 0.8], "sac": [0.1, 0.4, 0.6], "cmaes": [-0.5, 0.0, 0.0]}


def write_learners_data(docs: Path) -> None:
    """``docs/learners/{flights.csv, curves.csv, runs.json}`` as ``compare_learners evaluate``
    writes them, synthetic."""
    folder = docs / "learners"
    folder.mkdir(parents=True)
    rmse = _learners_rmse(np.random.default_rng(0))
    flights = [
        [name, seed, s, FIRST + f, repr(float(r[k, f]))]
        for (name, seed), r in rmse.items()
        for k, s in enumerate(SUITE)
        for f in range(FLIGHTS)
    ]
    _write_csv(
        folder / "flights.csv", ["learner", "seed", "scenario", "flight", "rmse_nt"], flights
    )
    anchors = {s: {"tuned_constant": 3.0, "privileged": 2.0} for s in SUITE}
    anchors[FLAT] = {"tuned_constant": 3.0, "privileged": 3.5}
    points = []
    for name, scores in CURVE.items():
        for seed in range(5):
            for k, score in enumerate(scores):
                steps = 25_000 * (k + 1) + (7 * seed if k == len(scores) - 1 else 0)
                for s in SUITE:
                    v = 3.0 - score if s != FLAT else 99.0  # FLAT has no validation headroom
                    points.append([name, seed, steps, 70.0 * (k + 1), 60.0 * (k + 1), s, 4, v])
    header = "learner seed timesteps seconds train_seconds scenario flights validation_rmse_nt"
    _write_csv(folder / "curves.csv", header.split(), points)
    runs = [
        {
            "learner": name,
            "seed": seed,
            "timesteps": 75_000,
            "minutes": 4.0 + seed,
            "validation_flights": 4,
            "kept_timesteps": 50_000,
            "best_validation_score": 0.9,
            "hyperparams": {"eval_episodes": 28},
        }
        for name in ("ppo", "recurrent_ppo", "sac", "cmaes")
        for seed in range(4 if name == "recurrent_ppo" else 5)
    ]
    meta = {
        "command": "python -m experiments.compare_learners evaluate --episodes 10",
        "date": "2026-01-02",
        "test_flights": {"first_seed": FIRST, "per_scenario": FLIGHTS},
        "scenarios": list(SUITE),
        "validation_anchors": {"4": anchors},
        "runs": runs,
    }
    (folder / "runs.json").write_text(json.dumps(meta, indent=1))


def _table(page: str, heading: str) -> list[list[str]]:
    """The cells of the first table after ``heading``."""
    part = page.split(heading, 1)[1]
    lines = part[part.index("\n|") + 1 :].split("\n\n", 1)[0].splitlines()
    return [[c.strip() for c in line.strip("|").split("|")] for line in lines]


@pytest.fixture(scope="module")
def learners_site(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, str]]:
    docs = tmp_path_factory.mktemp("learners") / "docs"
    shutil.copytree(ROOT / "docs" / "paper", docs / "paper")
    for folder in ("ppo", "general", "discovery"):
        shutil.copytree(ROOT / "docs" / folder, docs / folder)
    write_learners_data(docs)
    out = docs.parent / "out"
    return out, generate(out, docs)


@pytest.mark.slow  # the synthetic benchmark's bootstraps: about 10 s
def test_the_learners_page_has_every_learner_and_scenario(
    learners_site: tuple[Path, dict[str, str]],
) -> None:
    _, pages = learners_site
    page = pages["learners.md"]
    assert "* [Learners for the general tuner](learners.md)" in pages["index.md"]
    assert "gets its page when" not in pages["index.md"]
    rmse = _table(page, "### Mean RMSE [nT]")
    assert rmse[0][1:8] == [f"`{s}`" for s in SUITE]
    learners = ["`ppo`", "`recurrent_ppo`", "`sac`", "`cmaes`"]  # LEARNERS' order
    assert [r[0] for r in rmse[2:]] == [*learners, "`tuned_constant`", "`privileged`", "`fis`"]
    for row in rmse[2:6]:  # a mean and its interval over seeds in every cell
        assert all(re.fullmatch(r"[-\d.e]+ \[[-\d.e]+, [-\d.e]+\]", c) for c in row[1:9]), row
    assert rmse[3][9] == "5.5 (4.0–7.0)"  # recurrent_ppo's minutes: seeds 0–3
    scores = _table(page, "### Normalized score")
    assert scores[0][1:-1] == [f"`{s}`" for s in SUITE if s != FLAT]
    assert "without headroom" in page and f"`{FLAT}`." in page
    cmaes = next(r for r in scores if r[0] == "`cmaes`")
    assert all(c.startswith(("0.00", "-0.00")) for c in cmaes[1:]), cmaes  # tc itself scores 0
    tail = _table(page, "## The tail")
    assert [r[0] for r in tail[2:]] == ["`tuned_constant`", *learners]
    assert tail[2][1:] == next(r for r in tail if r[0] == "`cmaes`")[1:]  # cmaes is tc
    assert f"{FLIGHTS} test flights per scenario (seeds {FIRST:,}–{FIRST + FLIGHTS - 1:,}" in page


@pytest.mark.slow  # the synthetic benchmark's bootstraps: about 10 s
def test_the_learners_bar_and_verdict(learners_site: tuple[Path, dict[str, str]]) -> None:
    _, pages = learners_site
    page = pages["learners.md"]
    bar = {r[0]: r for r in _table(page, "## The bar for a shipped general policy")[2:]}
    assert bar["`ppo`"][-1] == "4 of 4"
    assert bar["`sac`"][1].startswith("**not met**: `noise_bursts` seed 3 (+0.5")
    assert bar["`sac`"][-1] == "3 of 4"
    assert [c.split(":")[0] for c in bar["`cmaes`"][1:5]] == ["met", "met", "met", "**not met**"]
    assert "* The bar for a shipped general policy is met by **`ppo`**." in page
    assert "Best by the IQM of the normalized score over seeds × scenarios: **`ppo`**" in page
    agg = {r[0]: r for r in _table(page, "## Over seeds × scenarios (rliable)")[2:]}
    assert agg["`ppo`"][-1] == "–" and agg["`cmaes`"][-1].startswith("0.00")  # P(cmaes > ppo)
    assert agg["`recurrent_ppo`"][1] == "4"


@pytest.mark.slow  # the synthetic benchmark's bootstraps: about 10 s
def test_the_learners_curves_and_figures(learners_site: tuple[Path, dict[str, str]]) -> None:
    out, pages = learners_site
    rows = list(csv.DictReader(pages["learners_curves.csv"].splitlines()))
    ppo = [r for r in rows if r["learner"] == "ppo"]
    assert [float(r["score"]) for r in ppo] == CURVE["ppo"]  # FLAT left out of the mean
    assert [r["timesteps"] for r in ppo] == ["25000", "50000", "75014"]  # the last: mean steps
    assert [r["seeds"] for r in ppo] == ["5"] * 3
    assert "{download}`learners_curves.csv`" in pages["learners.md"]
    for name in ("learners_curves.png", "learners_profiles.png"):
        assert (out / name).read_bytes().startswith(b"\x89PNG"), name
        assert f"]({name})" in pages["learners.md"]


def test_partial_learners_data_is_a_one_line_error(tmp_path: Path) -> None:
    docs = tmp_path / "docs"
    for folder in ("paper", "ppo", "general", "discovery"):
        shutil.copytree(ROOT / "docs" / folder, docs / folder)
    write_learners_data(docs)
    (docs / "learners" / "curves.csv").unlink()
    done = run(tmp_path / "out", docs)
    assert done.returncode == 2
    assert done.stderr.strip().count("\n") == 0 and "docs/learners/curves.csv" in done.stderr


# --- the adaptive filters' page on synthetic data -----------------------------------------------


def write_adaptive_data(docs: Path) -> None:
    """``docs/results/adaptive_benchmark.json`` as ``experiments/adaptive_benchmark.py`` writes
    it, synthetic: on ``noise_bursts`` ``vbakf`` beats ``general`` and ``constant`` by 1 nT on
    every flight; on ``nominal`` ``imm`` diverges on one flight and ties ``general``."""
    from agents.comparison.adaptive import summarize

    rng = np.random.default_rng(1)
    seeds = list(range(400_000, 400_000 + FLIGHTS))
    flights: dict = {}
    for scenario, offsets in (
        ("nominal", {"constant": 0.0, "imm": 0.0, "general": 0.0, "tuned_constant": 0.0}),
        ("noise_bursts", {"constant": 1.0, "vbakf": 0.0, "general": 1.0, "tuned_constant": 0.5}),
    ):
        base = rng.uniform(1.0, 3.0, FLIGHTS)
        flights[scenario] = {}
        for name, off in offsets.items():
            rmse = base + off + rng.normal(0.0, 0.01, FLIGHTS)
            div = [
                1.0 if (scenario, name) == ("nominal", "imm") and k == 0 else 0.0
                for k in range(FLIGHTS)
            ]
            flights[scenario][name] = {
                "rmse_nt": rmse.tolist(),
                "divergences": div,
                "outliers_rejected": [0.0] * FLIGHTS,
            }
    run = {
        "command": "python experiments/adaptive_benchmark.py --episodes 10",
        "date": "2026-01-02",
    }
    record = {
        "runs": [run],
        "seeds": seeds,
        "scenarios": list(flights),
        "policies": ["constant", "imm", "vbakf", "general", "tuned_constant"],
        "tables": summarize(flights),
        "flights": flights,
    }
    (docs / "results").mkdir(parents=True, exist_ok=True)
    (docs / "results" / "adaptive_benchmark.json").write_text(json.dumps(record))


def test_the_adaptive_page_says_what_its_data_show(tmp_path: Path) -> None:
    docs = tmp_path / "docs"
    for folder in ("paper", "ppo", "general", "discovery"):
        shutil.copytree(ROOT / "docs" / folder, docs / folder)
    write_adaptive_data(docs)
    pages = generate(tmp_path / "out", docs)
    page = pages["adaptive.md"]
    assert "* [Adaptive filters and tuners on fresh test flights](adaptive.md)" in pages["index.md"]
    assert "seeds 400,000–400,009" in page
    assert "* `nominal`: diverged: `imm` (1)." in page
    assert "`noise_bursts` (R moves): `vbakf` is better than `constant`" in page
    assert (
        "beats the learned `general` tuner** beyond the paired interval on `noise_bursts` (`vbakf`)"
        in page
    )
    rmse = _table(page, "## Mean RMSE [nT]")
    assert rmse[0] == ["policy", "`nominal`", "`noise_bursts`"]
    assert [r[0] for r in rmse[2:]] == [
        "`constant`",
        "`vbakf`",
        "`imm`",
        "`tuned_constant`",
        "`general`",
    ]
    assert rmse[3][1] == "–" and rmse[3][2].endswith("▼")  # vbakf: not flown on nominal
    divergences = _table(page, "## Divergences")
    assert divergences[4][1] == "1/10"
    versus = _table(page, "## The best adaptive filter against the learned `general` tuner")
    assert versus[2][:2] == ["`nominal`", "`imm`"] and versus[2][-1] == "same"
    assert versus[3][:2] == ["`noise_bursts`", "`vbakf`"] and versus[3][-1] == "**filter better**"


def test_the_which_method_howto_quotes_the_adaptive_page() -> None:
    """Every figure the how-to quotes from the benchmark (the sections before its costs) is a
    figure of the committed results page."""
    howto = (ROOT / "docs" / "howto" / "which-method.md").read_text()
    quoted = howto.split("## What they cost")[0].split("## The answer")[1]
    page = (RESULTS / "adaptive.md").read_text()
    cells = set(re.findall(r"(?<![\d.])\d+\.\d+(?![\d.])", page))
    figures = re.findall(r"(?<![\d.e])\d+\.\d+(?![\d.])", quoted)
    assert len(figures) > 30
    assert [f for f in figures if f not in cells] == []
