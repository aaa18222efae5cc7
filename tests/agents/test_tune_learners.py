"""``aeromag tune --learner`` (:mod:`agents.search.learners`, the learners' spaces of
:mod:`agents.search.space`): bad spaces, ``cmaes`` and refused output sets get one line before any
Ray starts (default suite); a quick search on the session's Ray writes a learners file that
training reads, holding the best trial's sample (``-m ray``)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from aeromag_env.errors import HyperparameterError
from agents.search.learners import OUTPUTS, SEARCHED
from agents.search.space import (
    LEARNER_SPACES,
    LEARNER_SPACES_SCHEMA,
    SPACE_SCHEMA,
    read_learner_space,
)
from agents.training.learners import HYPERPARAMS, learner_hyperparams
from tests._helpers import run_cli

GAMMA = {"distribution": "uniform", "low": 0.6, "high": 0.9}


def _spaces(tmp_path: Path, learners: object, name: str = "spaces.json") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps({"version": 1, "learners": learners}))
    return path


@pytest.mark.parametrize("learner", SEARCHED)
def test_shipped_spaces_read_and_tune_keys_of_the_learners_algo(learner) -> None:
    space = read_learner_space(learner, LEARNER_SPACES)
    assert space and set(space) <= set(learner_hyperparams(learner).algo.model_fields_set)


def test_the_learners_schema_draws_as_the_ppo_spaces_schema() -> None:
    """The two schemas' distributions are one definition, copied: they must not drift."""
    ours = json.loads(LEARNER_SPACES_SCHEMA.read_text(encoding="utf-8"))["$defs"]["dimension"]
    ppo = json.loads(SPACE_SCHEMA.read_text(encoding="utf-8"))["$defs"]["dimension"]
    assert ours == ppo


@pytest.mark.parametrize(
    ("learners", "message"),
    [
        ({"cmaes": {"gamma": GAMMA}}, 'searches: recurrent_ppo, sac, tqc, got "cmaes"'),
        ({"ppo": {"gamma": GAMMA}}, 'got "ppo"'),
        ({"sac": {"n_epochs": GAMMA}}, "sac.n_epochs: not a hyperparameter of sac's algo; valid"),
        (
            {"tqc": {"gamma": GAMMA, "clip_range": GAMMA}},
            "clip_range: not a hyperparameter of tqc's algo; valid: learning_rate",
        ),
        (
            {"sac": {"gamma": {"distribution": "uniform", "low": 0.6, "high": 1.5}}},
            "sac.gamma: 1.5 is no valid gamma: must be a number in (0, 1], got 1.5",
        ),
        (
            {"sac": {"gamma": {"distribution": "uniform", "low": 0.9, "high": 0.6}}},
            "sac.gamma: needs low < high",
        ),
        (
            {"sac": {"batch_size": {"distribution": "uniform", "low": 64, "high": 512}}},
            "sac.batch_size: uniform draws real numbers; batch_size is not one",
        ),
        (
            {"recurrent_ppo": {"ent_coef": {"distribution": "loguniform", "low": 0, "high": 1}}},
            "recurrent_ppo.ent_coef: loguniform needs low > 0",
        ),
        (
            {"sac": {"batch_size": {"distribution": "choice", "values": [128, 1.5]}}},
            "1.5 is no valid batch_size: must be an integer ≥ 1 and ≤ 65536",
        ),
        ({"sac": {"gamma": {"distribution": "normal", "low": 0.6}}}, "must be uniform, "),
        ({"sac": {"gamma": {"distribution": "uniform", "low": 0.6}}}, "uniform takes low and high"),
        ({"sac": {}}, "learners.sac: must be an object of 1 to 12 constructor parameters"),
        ({"tqc": {"gamma": GAMMA}}, "learners: no space for sac; it has tqc"),
    ],
)
def test_bad_learner_space_is_one_line_naming_the_field(tmp_path, learners, message) -> None:
    path = _spaces(tmp_path, learners)
    with pytest.raises(HyperparameterError) as info:
        read_learner_space("sac", path)
    text = str(info.value)
    assert text.startswith(f"bad search space in {path}: learners") and message in text
    assert "\n" not in text


def test_a_space_of_mixed_annotations_takes_each_of_its_types(tmp_path) -> None:
    """SAC's ``ent_coef`` is a number or ``"auto"``: both are valid values, a word is not."""
    auto = {"ent_coef": {"distribution": "choice", "values": ["auto", 0.1, "auto_0.5"]}}
    assert read_learner_space("sac", _spaces(tmp_path, {"sac": auto})) == auto
    bad = {"ent_coef": {"distribution": "choice", "values": ["often"]}}
    with pytest.raises(HyperparameterError, match='"often" is no valid ent_coef: must be a num'):
        read_learner_space("sac", _spaces(tmp_path, {"sac": bad}))


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--learner", "cmaes"], "aeromag tune does not search cmaes: "),
        (["--learner", "sac", "--scenario", "paper"], "--scenario must be suite for learner sac"),
    ],
)
def test_refused_learner_or_scenario_exits_2_before_ray(tmp_path, capsys, argv, message) -> None:
    out = tmp_path / "out"
    assert run_cli(["tune", *argv, "--quick", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not out.exists()


def test_bad_learner_space_on_the_command_line_exits_2_before_ray(tmp_path, capsys) -> None:
    path = _spaces(tmp_path, {"sac": {"n_epochs": GAMMA}})
    out = tmp_path / "out"
    argv = ["tune", "--learner", "sac", "--space", str(path), "--quick", "--out", str(out)]
    assert run_cli(argv) == 2
    err = capsys.readouterr().err
    assert "not a hyperparameter of sac's algo" in err and err.count("\n") == 1
    assert not out.exists()


def test_output_set_refused_when_the_base_learners_file_is_a_target(tmp_path, capsys) -> None:
    """Tuning again from a previous result into its own folder: ``out/learners.json`` is both
    the base hyperparameter file and an output."""
    out = tmp_path / "out"
    out.mkdir()
    target = out / "learners.json"
    target.write_bytes(HYPERPARAMS.read_bytes())
    argv = ["tune", "--learner", "tqc", "--hyperparams", str(target), "--quick", "--out", str(out)]
    assert run_cli(argv) == 2
    err = capsys.readouterr().err
    assert "is the input file" in err and err.count("\n") == 1
    assert target.read_bytes() == HYPERPARAMS.read_bytes()
    assert [p.name for p in out.iterdir()] == ["learners.json"]


@pytest.mark.ray
def test_quick_learner_search_writes_the_best_trial_into_a_learners_file(
    tmp_path, capsys, local_ray
) -> None:
    """2 quick SAC trials on the session's 2 CPUs (2048 steps, validations at 0, 1024 and 2048
    steps on 7 flights each): ``learners.json`` is the base file with SAC's algo the best trial's
    sample over the base, and loads as ``aeromag train --learner sac --hyperparams`` reads it."""
    out = tmp_path / "out"
    argv = ["tune", "--learner", "sac", "--quick", "--seed", "1", "--out", str(out), "--ray"]
    assert run_cli(argv) == 0
    assert "best: trial" in capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == sorted(OUTPUTS)
    summary = json.loads((out / "tune.json").read_text())
    trials, space = summary["trials"], read_learner_space("sac")
    assert summary["learner"] == "sac" and summary["timesteps"] == 2048
    assert len(trials) == 2 and all(t["error"] is None for t in trials)
    for t in trials:  # validations at 0, 1024, 2048 steps; ASHA's first rung after the second
        assert 2 <= t["reports"] <= 3
        assert t["stopped_by_asha"] == (t["timesteps"] < 2048)
        assert t["best_validation_score"] <= t["last_validation_score"]
        assert set(t["config"]) == set(space)
        assert 1e-4 <= t["config"]["learning_rate"] <= 3e-3 and 0.5 <= t["config"]["gamma"] <= 0.9
        assert t["config"]["batch_size"] in space["batch_size"]["values"]
    best = min(trials, key=lambda t: t["best_validation_score"])
    assert summary["best"] == best
    tuned = learner_hyperparams("sac", out / "learners.json")  # what aeromag train reads
    base = learner_hyperparams("sac")
    assert tuned.algo == base.algo.with_values(**best["config"])
    assert tuned.comment is not None
    assert tuned.comment.startswith("Tuned by aeromag tune --learner sac")
    assert tuned.model_dump(exclude={"algo", "comment"}) == base.model_dump(
        exclude={"algo", "comment"}
    )
    for other in ("tqc", "recurrent_ppo", "cmaes"):  # the other learners as they were
        assert learner_hyperparams(other, out / "learners.json") == learner_hyperparams(other)


def test_a_search_record_names_the_checkouts_files_by_their_repository_path(
    tmp_path, monkeypatch
) -> None:
    from agents.search.space import LEARNER_SPACES, recorded_path

    repo = LEARNER_SPACES.parents[3]
    monkeypatch.chdir(repo)
    assert recorded_path(LEARNER_SPACES) == "agents/search/spaces/tune_space_learners.json"
    assert (
        recorded_path("agents/training/hyperparams/learners.json")
        == "agents/training/hyperparams/learners.json"
    )
    outside = tmp_path / "mine.json"  # not under the working directory: as given
    assert recorded_path(outside) == str(outside)
