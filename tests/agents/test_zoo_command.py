"""``python -m agents.training.zoo FILE`` writes FILE and nothing else (the learners' recipes are
rewritten only by the bare command, in the package's hyperparameter folder)."""

from __future__ import annotations

from pathlib import Path

import yaml

from agents.training.zoo import main


def test_a_named_target_is_the_only_file_written(tmp_path: Path, monkeypatch, capsys) -> None:
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    assert main(["zoo_mine.yml"]) == 0
    assert sorted(p.name for p in work.iterdir()) == ["zoo_mine.yml"]
    recipe = yaml.safe_load((work / "zoo_mine.yml").read_text(encoding="utf-8"))
    assert "AeroMag/NonstationaryDense-v0" in recipe
    assert capsys.readouterr().out.splitlines() == ["wrote zoo_mine.yml"]
