"""The results pages under ``docs/results/`` are what ``scripts/results_pages.py`` makes from the
committed results files: regenerating them gives the committed pages, and a changed number in a
results file changes its page.

The script runs in a subprocess (tests import nothing from ``scripts/`` or ``experiments/``).
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "scripts" / "results_pages.py"
RESULTS = ROOT / "docs" / "results"


def generate(out: Path, docs: Path = ROOT / "docs") -> dict[str, str]:
    """Run the generator into ``out``; the pages it wrote, by name."""
    subprocess.run(
        [sys.executable, str(SCRIPT), "--docs", str(docs), "--out", str(out)],
        check=True,
        capture_output=True,
        text=True,
    )
    return {p.name: p.read_text() for p in sorted(out.glob("*.md"))}


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
    committed = {p.name: p.read_text() for p in sorted(RESULTS.glob("*.md"))}
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
