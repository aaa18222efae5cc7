"""The environment's settings as data: the observation registry, the presets, the generated
layouts.

The observation space comes from the registry only: an observation added anywhere else (a write
into the observation vector outside the writers, a writer without an entry, an entry without a
writer) fails here. Every registered id and every shipped policy names a preset.
"""

from __future__ import annotations

import ast
import dataclasses
import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import aeromag_env  # noqa: F401  (registers the environment)
from aeromag_env.compensation.kernel_layout import ACC, INTS, N_ACC, N_INT, N_PAR, PAR, Acc
from aeromag_env.configs import from_dict, to_json
from aeromag_env.environment import observe
from aeromag_env.environment.config import PRESETS, EnvConfig, env_config
from aeromag_env.environment.ids import registered_ids
from aeromag_env.environment.layout import N_RUN, OUT, RUN, STEP_PAR, Run
from aeromag_env.environment.observations import NAMES, REGISTRY, entry, observation_id
from aeromag_env.environment.spaces import observation_names
from aeromag_env.errors import ConfigError
from agents.policies import SHIPPED
from agents.policies.numpy_policy import NumpyPPOPolicy

ENVIRONMENT = Path(observe.__file__).parent
HYPERPARAMS = Path(__file__).parents[2] / "agents" / "training" / "hyperparams" / "ppo.json"


def _subscript_writes(tree: ast.AST, name: str) -> list[int]:
    """Lines that assign into ``name[...]`` (plain or augmented)."""
    lines = []
    for node in ast.walk(tree):
        targets = node.targets if isinstance(node, ast.Assign) else []
        if isinstance(node, ast.AugAssign):
            targets = [node.target]
        for t in targets:
            for sub in ast.walk(t):
                if (
                    isinstance(sub, ast.Subscript)
                    and isinstance(sub.value, ast.Name)
                    and sub.value.id == name
                ):
                    lines.append(node.lineno)
    return lines


def test_only_the_writers_write_the_observation_and_each_entry_has_one():
    """Every registry entry has exactly one compiled writer (an ``observation_id`` and one
    guarded write in :func:`observe.observe`), there is no writer without an entry, and no other
    module of the environment writes into an observation vector."""
    tree = ast.parse((ENVIRONMENT / "observe.py").read_text())
    ids = [
        node.args[0].value
        for node in ast.walk(tree)
        if isinstance(node, ast.Call)
        and getattr(node.func, "id", None) == "observation_id"
        and isinstance(node.args[0], ast.Constant)
    ]
    assert sorted(ids) == sorted(NAMES), "observe.py's ids are not the registry's names"
    body = next(n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef) and n.name == "observe")
    guarded = [n for n in body.body if isinstance(n, ast.If)]
    assert len(guarded) == len(REGISTRY), "one guarded write per registry entry"
    for module in sorted(ENVIRONMENT.glob("*.py")):
        if module.name != "observe.py":
            writes = _subscript_writes(ast.parse(module.read_text()), "obs")
            assert not writes, f"{module.name} writes an observation at lines {writes}"


def test_entries_are_complete_and_ids_are_positions():
    assert len(set(NAMES)) == len(NAMES)
    for i, e in enumerate(REGISTRY):
        assert observation_id(e.name) == i and entry(e.name) is e
        assert e.description and e.unit and e.low < e.high


@pytest.mark.parametrize("name", list(PRESETS))
def test_each_presets_observation_columns_are_its_registry_entries(name):
    """The observation space's size, names and bounds are the preset's registry entries; a few
    steps write every column within its bounds, and every column changes from the zeros of
    reset on some step."""
    env = gym.make("AeroMag/Nonstationary-v0", preset=name, duration_s=300.0)
    config = env.unwrapped.config
    names = observation_names(config)
    assert names == PRESETS[name].observations and set(names) <= set(NAMES)
    space = env.observation_space
    assert space.shape == (len(names),)
    np.testing.assert_array_equal(space.low, [entry(n).low for n in names])
    np.testing.assert_array_equal(space.high, [entry(n).high for n in names])
    obs, _ = env.reset(seed=100_000)
    rows = [obs]
    rng = np.random.default_rng(0)
    for _ in range(30):
        obs, *_ = env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
        rows.append(obs)
    rows_array = np.array(rows)
    assert np.all(rows_array >= space.low) and np.all(rows_array <= space.high)
    changed = np.any(rows_array[1:] != 0.0, axis=0)
    assert changed.all(), f"columns never written: {np.array(names)[~changed].tolist()}"


def test_every_registered_id_and_every_shipped_policy_names_a_preset():
    for id_, kwargs in registered_ids().items():
        assert kwargs["preset"] in PRESETS, id_
        assert gym.registry[id_].kwargs == kwargs
        config = gym.make(id_).unwrapped.config
        expected = PRESETS[kwargs["preset"]]
        if "scenario" in kwargs:
            expected = dataclasses.replace(expected, scenario=kwargs["scenario"])
        assert config == expected, id_
    for name, path in SHIPPED.items():
        policy = NumpyPPOPolicy.load(path)
        preset = policy.env_kwargs.get("preset")
        assert policy.env_kwargs == {"preset": preset} and preset in PRESETS, name
        env = policy.make_env()
        assert env.observation_space.shape == (policy.n_obs,)
        config = env.unwrapped.config
        assert dataclasses.replace(config, scenario="nominal") == PRESETS[preset]


def test_the_training_file_names_the_shipped_policies_presets():
    """The hyperparameter file's env_kwargs name the presets the shipped policies name (their
    first version's flat keys, which the policies' training.json keep, are read as the same
    presets: tests/environment/test_legacy.py)."""
    scenarios = json.loads(HYPERPARAMS.read_text())["scenarios"]
    for scenario, policy in (("nonstationary", "ppo"), ("suite", "general")):
        preset = NumpyPPOPolicy.load(SHIPPED[policy]).env_kwargs["preset"]
        settings = scenarios[scenario]["env_kwargs"]
        assert settings == {"preset": preset}
        assert from_dict(EnvConfig, settings) == PRESETS[preset] == env_config(**settings)


@pytest.mark.parametrize("name", list(PRESETS))
def test_presets_round_trip_through_json(name):
    config = PRESETS[name]
    assert from_dict(EnvConfig, json.loads(to_json(config))) == config
    assert env_config({"preset": name}) == config == env_config(preset=name)


@pytest.mark.parametrize(
    "kwargs, words",
    [
        ({"observations": ["log_ror", "log_qoq", "wind"]}, "unknown observation 'wind'"),
        ({"preset": "fancy"}, "unknown preset 'fancy'"),
        ({"config": {"turbo": True}}, "unknown field 'turbo'"),
        ({"action": {"permanent": "gate"}}, "needs action.mode='absolute'"),
    ],
)
def test_bad_configs_are_one_line_config_errors(kwargs, words):
    with pytest.raises(ConfigError) as err:
        gym.make("AeroMagCompensation-v0", **kwargs)
    assert "\n" not in str(err.value) and words in str(err.value)


def test_compiled_layouts_are_generated_from_their_field_lists():
    """Indices are consecutive from 0 in field order (the accumulators' at their widths), and
    the sizes are the field counts: the filter's and the environment's vectors have them."""
    from aeromag_env.compensation.kalman import FilterState
    from aeromag_env.environment.scenarios import make_episode

    for layout in (PAR, INTS, STEP_PAR, OUT):
        assert list(layout) == list(range(len(layout)))
    for starts, widths, size in ((ACC, list(Acc()), N_ACC), (RUN, list(Run()), N_RUN)):
        assert list(starts) == [sum(widths[:i]) for i in range(len(widths))]
        assert sum(widths) == size
    ep = make_episode("nominal", 0, 20.0)
    f = FilterState(ep.filter_cfg, ep.y, ep.t_b, ep.tdot_b, store_states=False)
    assert (f.par.size, f.ints.size, f.acc.size) == (N_PAR, N_INT, N_ACC)
    env = gym.make("AeroMagCompensation-v0").unwrapped
    env.reset(seed=0)
    assert env._out.size == len(OUT) and env._settings.par.size == len(STEP_PAR)
    assert env._run.size == N_RUN
