"""``aeromag tune`` (:mod:`agents.search.ppo`, :mod:`agents.search.space`): bad search spaces and
refused output sets get one line before any Ray starts (default suite); a tiny search on the
session's Ray writes a hyperparameter file that training accepts, holding the best trial's sample,
and
validates on validation seeds only (``-m ray``)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from aeromag_env.errors import AeromagError, HyperparameterError
from agents.evaluation.seeds import TEST_SEED_START, VALIDATION_SEEDS
from agents.search.ppo import OUTPUTS, ray_session
from agents.search.space import SPACE, read_space
from agents.training.hyperparameters import PPOHyperparams
from agents.training.hyperparams_file import read_hyperparams
from agents.training.ppo import HYPERPARAMS, load_hyperparams
from agents.training.validation import validation_seeds
from tests._helpers import run_cli

#: A small space of the three kinds of distribution (the shipped one has six keys).
SMALL = {
    "learning_rate": {"distribution": "loguniform", "low": 1e-4, "high": 1e-3},
    "gamma": {"distribution": "uniform", "low": 0.6, "high": 0.95},
    "clip_range": {"distribution": "choice", "values": [0.1, 0.3]},
}


def _space(tmp_path: Path, space: object, name: str = "space.json") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps({"version": 1, "space": space}))
    return path


def test_shipped_space_reads_and_tunes_keys_of_the_hyperparameter_file() -> None:
    space = read_space(SPACE)
    entry = read_hyperparams(HYPERPARAMS)["scenarios"]["nonstationary"]
    assert space and set(space) <= set(entry)


@pytest.mark.parametrize(
    ("space", "message"),
    [
        ({"learning_rat": SMALL["learning_rate"]}, "tunable hyperparameter: n_envs, n_steps"),
        ({"env_kwargs": {"distribution": "choice", "values": [{}]}}, 'got "env_kwargs"'),
        ({"gamma": {"distribution": "normal", "low": 0.6, "high": 0.9}}, "must be uniform, "),
        ({"gamma": {"distribution": "uniform", "low": 0.9, "high": 0.6}}, "needs low < high"),
        ({"gamma": {"distribution": "uniform", "low": 0.9, "high": 1.5}}, "1.5 is no valid gamma"),
        ({"ent_coef": {"distribution": "loguniform", "low": 0, "high": 0.1}}, "low > 0"),
        ({"gamma": {"distribution": "uniform", "low": 0.6}}, "uniform takes low and high"),
        ({"gamma": {"distribution": "choice", "values": []}}, "list of 1 to 64 values"),
        ({"n_steps": {"distribution": "uniform", "low": 64, "high": 512}}, "use randint or choice"),
        ({"gamma": {"distribution": "randint", "low": 0, "high": 1}}, "randint draws integers"),
        ({"batch_size": {"distribution": "choice", "values": [64, 1]}}, "1 is no valid batch_size"),
        ({}, "space: must be an object of 1 to 12"),
    ],
)
def test_bad_space_is_one_line_naming_the_field(tmp_path, space, message) -> None:
    path = _space(tmp_path, space)
    with pytest.raises(HyperparameterError) as info:
        read_space(path)
    text = str(info.value)
    assert text.startswith(f"bad search space in {path}: space") and message in text
    assert "\n" not in text


def test_bad_space_on_the_command_line_exits_2_before_ray(tmp_path, capsys) -> None:
    path = _space(tmp_path, {"gamma": {"distribution": "uniform", "low": 0.9, "high": 0.6}})
    out = tmp_path / "out"
    assert run_cli(["tune", "--space", str(path), "--quick", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "needs low < high" in err and err.count("\n") == 1
    assert not out.exists()


@pytest.mark.parametrize("option", ["--space", "--hyperparams"])
def test_output_set_refused_when_a_target_is_an_input(tmp_path, capsys, option) -> None:
    """E.g. tuning again from a previous result into its own folder: ``out/ppo.json`` is both
    the base hyperparameter file and an output."""
    out = tmp_path / "out"
    out.mkdir()
    source = SPACE if option == "--space" else HYPERPARAMS
    target = out / ("ppo.json" if option == "--hyperparams" else "tune.json")
    target.write_bytes(source.read_bytes())
    before = target.read_bytes()
    assert run_cli(["tune", option, str(target), "--quick", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "is the input file" in err and err.count("\n") == 1
    assert target.read_bytes() == before and sorted(p.name for p in out.iterdir()) == [target.name]


@pytest.mark.parametrize(
    ("argv", "message"),
    [(["--samples", "0"], "--samples must be in [1, 1000]"), (["--seed", "-1"], "--seed must")],
)
def test_bad_options_exit_2(tmp_path, capsys, argv, message) -> None:
    assert run_cli(["tune", "--out", str(tmp_path / "out"), *argv]) == 2
    assert message in capsys.readouterr().err


def test_without_the_ray_extra_one_line(monkeypatch) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray raises ImportError
    needs = r"^aeromag tune needs the ray extra: pip install"
    with pytest.raises(AeromagError, match=needs), ray_session(None):
        pass


def test_validation_seeds_are_validation_seeds() -> None:
    seeds = validation_seeds(40)
    assert seeds[0] == VALIDATION_SEEDS.start and len(seeds) == 40
    assert validation_seeds(len(VALIDATION_SEEDS))[-1] < TEST_SEED_START
    with pytest.raises(AeromagError, match="validation takes 1 to 50000 episodes"):
        validation_seeds(len(VALIDATION_SEEDS) + 1)


@pytest.mark.ray
def test_quick_search_writes_the_best_trial_as_a_hyperparameter_file(
    tmp_path, capsys, local_ray
) -> None:
    """3 trials of 3 chunks of 512 steps on the session's 2 CPUs (about 30 s): ASHA runs,
    ``ppo.json`` is the base entry with the best trial's sample and loads as training's file."""
    import ray

    out, space = tmp_path / "out", _space(tmp_path, SMALL)
    argv = [
        "tune",
        "--quick",
        "--space",
        str(space),
        "--samples",
        "3",
        "--timesteps",
        "1536",
        "--seed",
        "1",
        "--out",
        str(out),
        "--ray",
    ]
    assert run_cli(argv) == 0
    assert "best: trial" in capsys.readouterr().out
    assert ray.is_initialized()  # the session's Ray was joined, not shut down
    assert sorted(p.name for p in out.iterdir()) == sorted(OUTPUTS)
    summary = json.loads((out / "tune.json").read_text())
    trials = summary["trials"]
    assert len(trials) == 3 and all(t["error"] is None for t in trials)
    assert all(1 <= t["reports"] <= 3 for t in trials)
    assert any(t["reports"] == 3 and not t["stopped_by_asha"] for t in trials)
    for t in trials:  # every validation flight from the validation range, none a test flight
        first, last = t["validation_seeds"]
        assert VALIDATION_SEEDS.start == first <= last < VALIDATION_SEEDS.stop <= TEST_SEED_START
        assert last - first + 1 == summary["validation_episodes"] == 2
        assert 1e-4 <= t["config"]["learning_rate"] <= 1e-3 and 0.6 <= t["config"]["gamma"] <= 0.95
        assert t["config"]["clip_range"] in (0.1, 0.3)
    best = min(trials, key=lambda t: t["best_validation_rmse_nt"])
    assert summary["best"] == best
    read_hyperparams(out / "ppo.json")
    tuned = load_hyperparams("nonstationary", out / "ppo.json")  # what aeromag train reads
    base = read_hyperparams(HYPERPARAMS)["scenarios"]["nonstationary"]
    want = PPOHyperparams.from_entry({**base, **best["config"]}, tuned.version)
    assert tuned == want and tuned.to_entry()["gamma"] == best["config"]["gamma"]
