"""The environment settings of the first version's files (:mod:`aeromag_env.environment.legacy`):
each flat key becomes the field it set, the switches the observation and T_p action they built,
the settings a preset is name it, a bad flat value is one line naming the key the file gave;
old policy files load through it, and nothing else reads the flat keys."""

from __future__ import annotations

import ast
import json

import gymnasium as gym
import numpy as np
import pytest

import aeromag_env  # noqa: F401  (registers the environment)
from aeromag_env.configs import to_dict
from aeromag_env.environment.config import PRESETS, env_config
from aeromag_env.environment.legacy import LEGACY_KEYS, LEGACY_SWITCHES, is_legacy, upgrade
from aeromag_env.errors import ConfigError
from agents.policies.numpy_policy import NumpyPPOPolicy
from agents.policies.policy_file import write_policy
from tests._helpers import ROOT, assert_one_line_error, observations

PAPER = ("log_ror", "log_qoq")
POWERS = ("log_innovation_power", "log_mean_innovation_power")
#: A flat dict of the first version and the settings it meant, written out by hand.
TRANSLATIONS: list[tuple[dict, dict]] = [
    ({"extras": False}, {}),
    ({"extras": True}, {"observations": observations()}),
    ({"split_q": True}, {"action": {"permanent": "graded"}}),
    (
        {"extras": True, "split_q": True},
        {"observations": observations("log_qp_scale"), "action": {"permanent": "graded"}},
    ),
    (
        {"extras": True, "split_q": True, "qp_gate": True, "action_mode": "absolute"},
        {
            "observations": observations("log_qp_scale"),
            "action": {"permanent": "gate", "mode": "absolute"},
        },
    ),
    (
        {"extras": True, "turn_rate": True, "innovation_power": True},  # the columns' order
        {"observations": observations(*POWERS, "log_turn_rate")},
    ),
    (
        {"s_max": 3.0, "scale_limit": 1e4, "absolute_r_log10": [-1, 2]},
        {"action": {"s_max": 3.0, "scale_limit": 1e4, "r_log10": (-1.0, 2.0)}},
    ),
    (
        {"reward_form": "squared", "reward_scale_nt": 2.0, "divergence_penalty": -5.0},
        {"reward": {"form": "squared", "scale_nt": 2.0, "divergence_penalty": -5.0}},
    ),
    (
        {"scenario": "misspecified", "decision_window": 5, "extras": True, "duration_s": 60.0},
        {
            "scenario": "misspecified",
            "decision_window": 5,
            "duration_s": 60.0,
            "observations": observations(),
        },
    ),
]


@pytest.mark.parametrize(("flat", "meant"), TRANSLATIONS, ids=[str(f) for f, _ in TRANSLATIONS])
def test_each_flat_key_becomes_the_setting_it_made(flat, meant):
    upgraded = upgrade(flat)
    assert not is_legacy(upgraded)
    assert env_config(upgraded) == env_config(meant)
    env = gym.make("AeroMagCompensation-v0", **upgraded)  # what a policy's env_kwargs do
    assert env.unwrapped.config == env_config(meant)


#: The flat settings of the shipped runs (docs/*/training.json): the presets, field for field.
STORED = {
    "nonstationary": ROOT / "docs" / "ppo" / "training.json",
    "general": ROOT / "docs" / "general" / "training.json",
}


@pytest.mark.parametrize("preset", STORED)
def test_the_shipped_runs_flat_settings_are_their_presets(preset):
    flat = json.loads(STORED[preset].read_text())["hyperparams"]["env_kwargs"]
    assert is_legacy(flat)
    assert upgrade(flat) == {"preset": preset}
    assert env_config(upgrade(flat)) == PRESETS[preset]


def test_settings_of_today_are_kept_as_they_are():
    for settings in ({}, {"preset": "general", "duration_s": 60.0}, {"action": {"s_max": 3.0}}):
        upgraded = upgrade(settings)
        assert upgraded == settings and upgraded is not settings


def test_settings_that_are_no_preset_are_written_out():
    upgraded = upgrade({"extras": True, "s_max": 3.0})
    assert set(upgraded) == {"observations", "action", "reward"}
    assert upgraded["observations"] == list(observations())
    assert upgraded["action"] == {**to_dict(PRESETS["paper"].action), "s_max": 3.0}


@pytest.mark.parametrize(
    ("flat", "message"),
    [
        ({"s_max": float("nan")}, r"action\.s_max must be a finite number > 1 .*got nan$"),
        ({"reward_scale_nt": 0.0}, r"reward\.scale_nt .*\[nT\].*\(given as reward_scale_nt\)"),
        ({"reward_form": "cubic"}, r"reward\.form: one of .*\(given as reward_form\)"),
        ({"action_mode": "both"}, r"action\.mode: relative or absolute.*\(given as action_mode\)"),
        ({"absolute_q_log10": [1, 0]}, r"action\.q_log10 .*lo < hi.*given as absolute_q_log10"),
        ({"extras": "yes"}, "extras must be true or false, got 'yes'"),
        ({"split_q": 1}, "split_q must be true or false, got 1"),
        ({"qp_gate": True, "extras": True}, "qp_gate needs split_q=True and action_mode"),
        ({"innovation_power": True}, "innovation_power needs extras=True"),
        ({"extras": True, "preset": "general"}, r"mix the first version's flat keys \(extras\)"),
        ({"s_max": 3.0, "action": {}}, "with action; write presets and specs only"),
    ],
)
def test_a_bad_flat_value_is_one_line_naming_the_key_the_file_gave(flat, message):
    with pytest.raises(ConfigError) as info:
        upgrade(flat)
    assert_one_line_error(info, patterns=(message,))


def test_every_flat_key_is_translated():
    """The keys this module reads are every key of the first version beside today's fields."""
    assert set(LEGACY_KEYS) == {
        "action_mode",
        "s_max",
        "scale_limit",
        "absolute_q_log10",
        "absolute_r_log10",
        "absolute_qp_log10",
        "reward_form",
        "reward_scale_nt",
        "divergence_penalty",
    }
    assert set(LEGACY_SWITCHES) == {
        "extras",
        "split_q",
        "qp_gate",
        "innovation_power",
        "step_statistic",
        "turn_rate",
        "innovation_bias",
    }


def test_a_policy_file_of_the_first_version_loads_through_it(tmp_path):
    """The learners' page's PPO runs (docs/learners/policies/ppo_seed*.npz) carry flat keys:
    they load, their settings the ``general`` preset, and fly in their environment. A policy of
    flat settings no preset has loads with its settings written out."""
    path = ROOT / "docs" / "learners" / "policies" / "ppo_seed0.npz"
    with np.load(path, allow_pickle=False) as data:
        assert "extras" in json.loads(str(data["meta"]))["env_kwargs"]  # the file as written
    policy = NumpyPPOPolicy.load(path)
    assert policy.env_kwargs == {"preset": "general"}
    env = policy.make_env(duration_s=30.0)
    obs, _ = env.reset(seed=100_000)
    assert np.all(np.isfinite(env.step(policy.predict(obs)[0])[0]))

    n_obs = len(observations())
    arrays = {
        "obs_mean": np.zeros(n_obs),
        "obs_var": np.ones(n_obs),
        "obs_clip": np.array(10.0),
        "obs_eps": np.array(1e-8),
        "w_out": np.zeros((2, n_obs)),
        "b_out": np.zeros(2),
    }
    flat = {"extras": True, "s_max": 3.0}
    policy = NumpyPPOPolicy.load(write_policy(arrays, {"env_kwargs": flat}, tmp_path / "p.npz"))
    assert policy.env_kwargs == upgrade(flat)
    assert policy.make_env().observation_space.shape == (n_obs,)


def test_nothing_else_reads_the_flat_keys():
    """The first version's flat keys are read in the compatibility module only: no other
    module of the packages names one as a string (the error that refuses them imports their
    names from it; ``s_max``, ``scale_limit`` and ``divergence_penalty`` are also the names of
    today's spec fields)."""
    fields = {*to_dict(PRESETS["paper"].action), *to_dict(PRESETS["paper"].reward)}
    flat = {*LEGACY_KEYS, *LEGACY_SWITCHES} - fields
    found = []
    for package in ("aeromag_env", "agents"):
        for path in sorted((ROOT / package).rglob("*.py")):
            if path.name == "legacy.py":
                continue
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, ast.Constant) and node.value in flat:
                    found.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.value!r}")
    assert not found, found
