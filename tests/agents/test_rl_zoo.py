"""RL Baselines3 Zoo (rl_zoo3) trains on a registered id with our hyperparameters.

``agents/training/hyperparams/ppo_zoo.yml`` is made from ``ppo.json`` (:mod:`agents.training.zoo`):
the file in the repo must be what the converter makes now, its environment settings a preset,
and ``python -m rl_zoo3.train --gym-packages aeromag_env`` must train with it, its Monitor
recording each episode's RMSE, and evaluate with it: rl_zoo3 makes its evaluation environments
without the recipe's ``env_kwargs``, which the recipe's ``env_wrapper``
(:class:`agents.training.zoo.RecipeSettings`) gives them.
"""

from __future__ import annotations

import csv
import subprocess
import sys
from importlib.util import find_spec
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

import aeromag_env  # noqa: F401  (registers the ids)
from aeromag_env.environment.config import PRESETS
from agents.training.hyperparams_file import read_ppo
from agents.training.zoo import (
    HYPERPARAMS,
    WRAPPER,
    RecipeSettings,
    write_zoo_file,
    zoo_hyperparams,
)

# not imported here: importing rl_zoo3 replaces Gymnasium's TimeLimit process-wide (its
# gym_patches), which would change every later test's environments
pytestmark = pytest.mark.skipif(find_spec("rl_zoo3") is None, reason="rl_zoo3 not installed")


def test_the_zoo_file_is_made_from_ppo_json(tmp_path: Path) -> None:
    shipped = yaml.safe_load((HYPERPARAMS / "ppo_zoo.yml").read_text(encoding="utf-8"))
    fresh = yaml.safe_load(write_zoo_file(HYPERPARAMS / "ppo.json", tmp_path / "z.yml").read_text())
    assert shipped == fresh, "run `python -m agents.training.zoo` after changing ppo.json"
    hp = read_ppo(HYPERPARAMS / "ppo.json").scenarios["nonstationary"]
    entry = shipped["AeroMag/NonstationaryDense-v0"]  # trained on the training scenario
    assert entry["env_kwargs"] == hp.env_kwargs == {"preset": "nonstationary"}
    assert entry["env_wrapper"] == [{WRAPPER: {"preset": "nonstationary"}}]
    assert entry["gamma"] == hp.gamma
    assert entry["n_steps"] * entry["n_envs"] % entry["batch_size"] == 0
    assert shipped["AeroMag/Suite-v0"]["env_kwargs"] == {"preset": "general"}


@pytest.mark.slow
def test_rl_zoo3_trains_on_a_registered_id(tmp_path: Path) -> None:
    """4096 steps on 2 environments of 60-s flights (60 steps an episode: 10 samples a step at
    10 Hz), through the zoo's own command line; the model, the normaliser and a Monitor
    file with ``episode_rmse_nt`` per episode come out."""
    hyperparams = zoo_hyperparams(read_ppo(HYPERPARAMS / "ppo.json"))
    for entry in hyperparams.values():
        entry["env_kwargs"]["duration_s"] = 60.0
        entry["env_wrapper"][0][WRAPPER]["duration_s"] = 60.0
    conf = tmp_path / "zoo.yml"
    conf.write_text(yaml.safe_dump(hyperparams), encoding="utf-8")
    argv = [
        sys.executable,
        "-m",
        "rl_zoo3.train",
        "--algo",
        "ppo",
        "--env",
        "AeroMag/NonstationaryDense-v0",
        "--gym-packages",
        "aeromag_env",
        "--conf-file",
        str(conf),
        "-n",
        "4096",
        "--eval-freq",
        "-1",
        "--seed",
        "0",
        "--log-folder",
        str(tmp_path / "logs"),
        "--hyperparams",
        "n_envs:2",
        "--verbose",
        "0",
    ]
    run = subprocess.run(
        argv, cwd=tmp_path, capture_output=True, text=True, timeout=600, check=False
    )
    assert run.returncode == 0, run.stderr[-3000:]
    out = tmp_path / "logs" / "ppo" / "AeroMag-NonstationaryDense-v0_1"
    assert (out / "AeroMag-NonstationaryDense-v0.zip").stat().st_size > 0
    assert (out / "AeroMag-NonstationaryDense-v0" / "vecnormalize.pkl").is_file()
    rows = [
        row
        for f in sorted(out.glob("*.monitor.csv"))
        for row in csv.DictReader(f.read_text().splitlines()[1:])
    ]
    assert len(rows) >= 2 * (4096 // 2 // 61)  # every episode of both environments
    assert all(0.0 < float(row["episode_rmse_nt"]) < 1e3 for row in rows)
    assert all(row["l"] == "60" for row in rows)


def test_the_learners_zoo_files_are_made_from_learners_json(tmp_path: Path) -> None:
    from agents.training.learners import learner_hyperparams
    from agents.training.zoo import ZOO_ALGOS, write_learner_zoo_files

    fresh = write_learner_zoo_files(HYPERPARAMS / "learners.json", tmp_path)
    assert [p.name for p in fresh] == [f"{a}.yml" for a in ZOO_ALGOS.values()]
    for learner, path in zip(ZOO_ALGOS, fresh, strict=True):
        shipped = yaml.safe_load((HYPERPARAMS / path.name).read_text(encoding="utf-8"))
        assert shipped == yaml.safe_load(path.read_text()), "run `python -m agents.training.zoo`"
        (entry,) = shipped.values()
        hp = learner_hyperparams(learner)
        assert entry["gamma"] == hp.algo.gamma and entry["n_envs"] == hp.n_envs
        assert entry["env_kwargs"] == {"preset": "general"}
        assert entry["env_wrapper"] == [{WRAPPER: {"preset": "general"}}]


def test_the_recipe_wrapper_gives_an_environment_the_recipes_settings():
    """An environment made from the id alone (the ``paper`` preset, as rl_zoo3 makes its
    evaluation environments) is made again with the recipe's settings under its Monitor; one
    made with them is kept."""
    from stable_baselines3.common.monitor import Monitor

    bare = Monitor(gym.make("AeroMag/NonstationaryDense-v0"))
    assert bare.observation_space.shape == (len(PRESETS["paper"].observations),)
    wrapped = RecipeSettings(bare, preset="nonstationary")
    assert wrapped.env is bare and wrapped.unwrapped.scenario == "nonstationary_dense"
    config = wrapped.unwrapped.config
    assert config.observations == PRESETS["nonstationary"].observations
    assert config.action == PRESETS["nonstationary"].action
    obs, _ = wrapped.reset(seed=3)
    assert obs.shape == wrapped.observation_space.shape == (len(config.observations),)
    wrapped.step(np.zeros(wrapped.action_space.shape, np.float32))
    made = Monitor(gym.make("AeroMag/NonstationaryDense-v0", preset="nonstationary"))
    inner = made.env
    assert RecipeSettings(made, preset="nonstationary").env.env is inner


@pytest.mark.slow
def test_the_zoo_recipe_trains_past_its_first_evaluation(tmp_path: Path) -> None:
    """The documented command with the shipped recipe, 30 000 steps: the zoo evaluates at
    25 000 steps (its default ``--eval-freq``) on environments made for evaluation, which get
    the recipe's settings; the evaluation's results come out. About 4 minutes on 2 cores."""
    argv = [
        sys.executable,
        "-m",
        "rl_zoo3.train",
        "--algo",
        "ppo",
        "--env",
        "AeroMag/NonstationaryDense-v0",
        "--gym-packages",
        "aeromag_env",
        "--conf-file",
        str(HYPERPARAMS / "ppo_zoo.yml"),
        "-n",
        "30000",
        "--seed",
        "0",
        "--log-folder",
        str(tmp_path / "logs"),
    ]
    run = subprocess.run(
        argv, cwd=tmp_path, capture_output=True, text=True, timeout=3600, check=False
    )
    assert run.returncode == 0, run.stderr[-3000:]
    assert "Eval num_timesteps=25000" in run.stdout
    out = tmp_path / "logs" / "ppo" / "AeroMag-NonstationaryDense-v0_1"
    with np.load(out / "evaluations.npz") as evaluations:
        assert evaluations["timesteps"].tolist() == [25000]
        assert np.isfinite(evaluations["results"]).all()
    assert (out / "best_model.zip").stat().st_size > 0
    assert (out / "AeroMag-NonstationaryDense-v0.zip").stat().st_size > 0
