"""The evaluation and training jobs: the command line and the library door agree."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from aeromag_env.cli.main import main
from aeromag_env.errors import AeromagError
from aeromag_env.jobs.evaluate import evaluate
from aeromag_env.jobs.reports import jsonable


def test_evaluate_cli_and_library_write_the_same_set(tmp_path: Path, capsys) -> None:
    argv = ["--scenario", "nominal", "--policies", "constant,fis", "--episodes", "2", "--quiet"]
    assert main(["evaluate", *argv, "--no-html", "--out", str(tmp_path / "cli")]) == 0
    capsys.readouterr()
    done = evaluate("nominal", ["constant", "fis"], episodes=2, out=tmp_path / "lib", html=False)
    cli = (tmp_path / "cli" / "results.json").read_text()
    assert (tmp_path / "lib" / "results.json").read_text() == cli
    assert done.paths == (tmp_path / "lib" / "results.json", tmp_path / "lib" / "evaluation.png")
    assert json.loads(cli) == json.loads(json.dumps(jsonable(done.results["nominal"])))
    assert done.note is None


def test_evaluate_without_out_writes_nothing_and_refuses_in_one_line(tmp_path: Path) -> None:
    done = evaluate(["nominal"], ["constant"], episodes=1)
    assert done.paths == () and set(done.results) == {"nominal"}
    with pytest.raises(AeromagError, match=r"policies takes names of .* got 'nope'"):
        evaluate("nominal", ["nope"], out=tmp_path)
    with pytest.raises(AeromagError, match="distinct scenarios"):
        evaluate("nominal,nominal", ["fis"])
    assert not any(tmp_path.iterdir())


def test_train_policies_runs_each_seed_and_summarises_them(tmp_path: Path, monkeypatch) -> None:
    """The seeds' summary from each run's result (a stand-in for PPO: the job's bookkeeping is
    under test, not training); a failed seed is reported and the others complete."""
    import agents.training.ppo
    from aeromag_env.jobs.train import train

    def fake_train(scenario, timesteps, seed, out, *args):
        if seed == 3:
            raise ValueError("seed 3 broke")
        return {"best_validation_rmse_nt": 1.0 + seed, "timesteps": 100 * (seed + 1)}

    monkeypatch.setattr(agents.training.ppo, "train_ppo", fake_train)
    monkeypatch.setattr("aeromag_env.jobs.train._require_rl_extra", lambda: None)
    done = train(tmp_path, scenario="nonstationary", seeds=[0, 2, 3], html=False)
    rows = {r["seed"]: r for r in done.summary["seeds"]}
    assert [rows[s]["best_validation_rmse_nt"] for s in (0, 2)] == [1.0, 3.0]
    assert rows[3]["best_validation_rmse_nt"] is None and "seed 3 broke" in rows[3]["error"]
    assert done.summary["validation_rmse_nt_mean"] == 2.0  # [nT] mean of the finite seeds
    assert done.summary["validation_rmse_nt_sd"] == pytest.approx(2**0.5)
    assert [o.label.split()[1] for o in done.failed] == ["3"]
    assert done.paths == (tmp_path / "seeds.json",)
    assert json.loads((tmp_path / "seeds.json").read_text()) == done.summary
