"""The evaluation job (agents.jobs): the command line and the library door agree."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from aeromag_env.cli.main import main
from aeromag_env.errors import AeromagError
from aeromag_env.jobs.reports import jsonable
from agents.jobs import evaluate_policies


def test_evaluate_cli_and_library_write_the_same_set(tmp_path: Path, capsys) -> None:
    argv = ["--scenario", "nominal", "--policies", "constant,fis", "--episodes", "2", "--quiet"]
    assert main(["evaluate", *argv, "--no-html", "--out", str(tmp_path / "cli")]) == 0
    capsys.readouterr()
    done = evaluate_policies(
        "nominal", ["constant", "fis"], episodes=2, out=tmp_path / "lib", html=False
    )
    cli = (tmp_path / "cli" / "results.json").read_text()
    assert (tmp_path / "lib" / "results.json").read_text() == cli
    assert done.paths == (tmp_path / "lib" / "results.json", tmp_path / "lib" / "evaluation.png")
    assert json.loads(cli) == json.loads(json.dumps(jsonable(done.results["nominal"])))
    assert done.note is None


def test_evaluate_without_out_writes_nothing_and_refuses_in_one_line(tmp_path: Path) -> None:
    done = evaluate_policies(["nominal"], ["constant"], episodes=1)
    assert done.paths == () and set(done.results) == {"nominal"}
    with pytest.raises(AeromagError, match="unknown policy 'nope'"):
        evaluate_policies("nominal", ["nope"], out=tmp_path)
    with pytest.raises(AeromagError, match="distinct scenarios"):
        evaluate_policies("nominal,nominal", ["fis"])
    assert not any(tmp_path.iterdir())
