"""Fault injection: hostile ``--hyperparams`` files get one line naming the field and its range.

Every case is generated here from the shipped ``agents/training/hyperparams/ppo.json`` by class:
unreadable text, a document of the wrong kind, missing and unknown keys, wrong types, values
out of range and environment settings :class:`~aeromag_env.environment.env.EnvConfig` refuses.
Each must raise :class:`~aeromag_env.errors.HyperparameterError` from
:func:`agents.training.ppo.load_hyperparams` (before any training starts) with a one-line message
naming the file, the field and, for a value out of range, the allowed range. The models
(:mod:`agents.training.hyperparameters`) are checked here too: their defaults, their schema
(the committed file is the generated one) and their errors in Python.
"""

from __future__ import annotations

import copy
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from aeromag_env.cli.main import main
from aeromag_env.environment.scenarios import SCENARIOS, TRAINING_SCENARIOS
from aeromag_env.errors import HyperparameterError
from agents.training.ppo import HYPERPARAMS, VEC_ENVS, _ppo_kwargs, load_hyperparams
from tests._helpers import assert_one_line_error, examples

SHIPPED = json.loads(HYPERPARAMS.read_text(encoding="utf-8"))
SCHEMA = json.loads(HYPERPARAMS.with_name("ppo.schema.json").read_text(encoding="utf-8"))
HP = SHIPPED["scenarios"]["nonstationary"]
Doc = Any


def _hp(key: str, value: Any) -> Callable[[Doc], Doc]:
    def mutate(doc: Doc) -> Doc:
        doc["scenarios"]["nonstationary"][key] = value
        return doc

    return mutate


def _hp_del(key: str) -> Callable[[Doc], Doc]:
    def mutate(doc: Doc) -> Doc:
        del doc["scenarios"]["nonstationary"][key]
        return doc

    return mutate


def _sub(key: str, sub: str, value: Any) -> Callable[[Doc], Doc]:
    def mutate(doc: Doc) -> Doc:
        doc["scenarios"]["nonstationary"][key][sub] = value
        return doc

    return mutate


def _top(change: Callable[[Doc], Any]) -> Callable[[Doc], Doc]:
    return lambda doc: change(doc)


def _no(key: str) -> Callable[[Doc], Doc]:
    def mutate(doc: Doc) -> Doc:
        del doc[key]
        return doc

    return mutate


#: Document-level faults: (case, mutation of the shipped document, the message's problem).
DOC_FAULTS: list[tuple[str, Callable[[Doc], Doc], str]] = [
    ("a_list", lambda d: [d], "must be a JSON object.*list"),
    ("a_string", lambda d: "ppo", 'must be a JSON object.*"ppo"'),
    ("null", lambda d: None, "must be a JSON object"),
    ("a_number", lambda d: 5, "must be a JSON object"),
    ("empty_object", lambda d: {}, "version is missing"),
    ("no_scenarios", _no("scenarios"), r"^\S+: scenarios is missing"),
    ("version_text", _top(lambda d: {**d, "version": "5"}), "version.*integer"),
    ("version_zero", _top(lambda d: {**d, "version": 0}), r"version.*≥ 1"),
    ("unknown_top_key", _top(lambda d: {**d, "scenario": {}}), "scenario is unknown; valid"),
    ("scenarios_a_list", _top(lambda d: {**d, "scenarios": []}), "scenarios.*object"),
    (
        "scenarios_empty",
        _top(lambda d: {**d, "scenarios": {}}),
        "no PPO hyperparameters for 'nonstationary'",
    ),
    (
        "unknown_scenario",
        _top(lambda d: {**d, "scenarios": {**d["scenarios"], "windy": HP}}),
        "scenarios.windy is no valid name: must be a scenario name",
    ),
    (
        "scenario_a_list",
        _top(lambda d: {**d, "scenarios": {"nonstationary": [1]}}),
        "nonstationary.*object",
    ),
    *[
        (f"missing_{k}", _hp_del(k), f"scenarios.nonstationary.{k} is missing")
        for k in (
            "n_envs",
            "n_steps",
            "batch_size",
            "n_epochs",
            "learning_rate",
            "gamma",
            "gae_lambda",
            "ent_coef",
            "clip_range",
            "net_arch",
            "normalize_reward",
            "eval_every",
            "eval_episodes",
            "env_kwargs",
        )
    ],
    ("unknown_key", _hp("gama", 0.9), "scenarios.nonstationary.gama is unknown; valid: n_envs"),
    ("n_envs_text", _hp("n_envs", "8"), "n_envs.*integer"),
    ("n_envs_fraction", _hp("n_envs", 8.5), "n_envs.*integer"),
    ("n_envs_float", _hp("n_envs", 8.0), "n_envs.*integer"),
    ("n_envs_bool", _hp("n_envs", True), "n_envs.*integer"),
    ("n_envs_zero", _hp("n_envs", 0), r"n_envs.*≥ 1"),
    ("n_envs_negative", _hp("n_envs", -1), r"n_envs.*≥ 1"),
    ("n_steps_zero", _hp("n_steps", 0), r"n_steps.*≥ 1"),
    ("batch_size_one", _hp("batch_size", 1), r"batch_size.*≥ 2"),
    ("n_epochs_zero", _hp("n_epochs", 0), r"n_epochs.*≥ 1"),
    ("learning_rate_zero", _hp("learning_rate", 0), r"learning_rate must be a number in \(0, 1\]"),
    ("learning_rate_negative", _hp("learning_rate", -3e-4), r"learning_rate.*\(0, 1\]"),
    ("learning_rate_above_one", _hp("learning_rate", 1.5), r"learning_rate.*\(0, 1\].*got 1\.5"),
    ("learning_rate_word", _hp("learning_rate", "fast"), r"learning_rate.*lin_"),
    ("learning_rate_bad_schedule", _hp("learning_rate", "lin_x"), r"learning_rate.*lin_"),
    ("learning_rate_negative_schedule", _hp("learning_rate", "lin_-1"), r"learning_rate.*lin_"),
    ("learning_rate_zero_schedule", _hp("learning_rate", "lin_0"), r"learning_rate.*lin_"),
    ("learning_rate_list", _hp("learning_rate", [3e-4]), r"learning_rate"),
    ("gamma_text", _hp("gamma", "0.7"), "gamma.*number"),
    ("gamma_two", _hp("gamma", 2.0), r"gamma.*\(0, 1\]"),
    ("gamma_zero", _hp("gamma", 0), r"gamma.*\(0, 1\]"),
    ("gamma_negative", _hp("gamma", -0.1), r"gamma.*\(0, 1\]"),
    ("gamma_just_above_one", _hp("gamma", 1.000001), r"gamma.*\(0, 1\]"),
    ("gae_lambda_high", _hp("gae_lambda", 1.5), r"gae_lambda.*\[0, 1\]"),
    ("gae_lambda_negative", _hp("gae_lambda", -0.5), r"gae_lambda.*\[0, 1\]"),
    ("ent_coef_negative", _hp("ent_coef", -0.01), r"ent_coef.*\[0, 1\]"),
    ("ent_coef_above_one", _hp("ent_coef", 2), r"ent_coef.*\[0, 1\]"),
    ("train_scenario_null", _hp("train_scenario", None), "train_scenario must be .*got null"),
    ("clip_range_zero", _hp("clip_range", 0.0), r"clip_range.*\(0, 1\]"),
    ("clip_range_high", _hp("clip_range", 1.5), r"clip_range.*\(0, 1\]"),
    ("net_arch_text", _hp("net_arch", "64,64"), "net_arch.*list"),
    ("net_arch_word", _hp("net_arch", [64, "x"]), r"net_arch\.1.*integer"),
    ("net_arch_zero", _hp("net_arch", [64, 0]), r"net_arch\.1.*≥ 1"),
    ("net_arch_fraction", _hp("net_arch", [64.5]), r"net_arch\.0.*integer"),
    ("normalize_reward_number", _hp("normalize_reward", 1), "normalize_reward.*true or false"),
    ("prefetch_text", _hp("prefetch", "yes"), "prefetch.*true or false"),
    ("eval_every_zero", _hp("eval_every", 0), r"eval_every.*≥ 1"),
    ("eval_episodes_zero", _hp("eval_episodes", 0), r"eval_episodes.*≥ 1"),
    ("vec_env_unknown", _hp("vec_env", "gpu"), "vec_env.*batched"),
    ("train_scenario_unknown", _hp("train_scenario", "windy"), "train_scenario.*nonstationary"),
    ("train_scenario_number", _hp("train_scenario", 5), "train_scenario"),
    ("log_std_init_huge", _hp("log_std_init", 50.0), r"log_std_init.*\[-20, 2\]"),
    ("log_std_init_text", _hp("log_std_init", "-2"), "log_std_init.*number"),
    ("env_kwargs_a_list", _hp("env_kwargs", [1]), "env_kwargs.*object"),
    ("env_kwargs_unknown", _sub("env_kwargs", "extra_s", 1), "env_kwargs.*extra_s"),
    (
        "env_kwargs_bad_value",
        _sub("env_kwargs", "action", {"scale_limit": 0.5}),
        "env_kwargs: .*scale_limit",
    ),
    ("env_kwargs_bad_type", _sub("env_kwargs", "decision_window", "5"), "env_kwargs: .*decision"),
    ("env_kwargs_unknown_preset", _sub("env_kwargs", "preset", "windy"), "unknown preset 'windy'"),
    (
        "env_kwargs_flat_bad_type",  # a file of the first version: its flat keys, read as such
        _hp("env_kwargs", {"extras": "yes"}),
        "env_kwargs: extras must be true or false",
    ),
    (
        "env_kwargs_flat_and_preset",
        _sub("env_kwargs", "split_q", True),
        "env_kwargs: .*mix the first version's flat keys \\(split_q\\) with preset",
    ),
    ("pretrain_a_list", _hp("pretrain", []), "pretrain.*object"),
    (
        "pretrain_no_steps",
        lambda d: _hp("pretrain", {"epochs": 1})(d),
        "pretrain.steps is missing",
    ),
    ("pretrain_steps_zero", _sub("pretrain", "steps", 0), r"pretrain\.steps.*≥ 1"),
    ("pretrain_epochs_zero", _sub("pretrain", "epochs", 0), r"pretrain\.epochs.*≥ 1"),
    (
        "pretrain_threshold_negative",
        _sub("pretrain", "threshold_nt", -1.0),
        r"pretrain\.threshold_nt.*> 0",
    ),
    (
        "pretrain_lr_zero",
        _sub("pretrain", "learning_rate", 0.0),
        r"pretrain\.learning_rate.*\(0, 1\]",
    ),
    (
        "pretrain_bc_negative",
        _sub("pretrain", "bc_minibatches", -1),
        r"pretrain\.bc_minibatches.*≥ 0",
    ),
    (
        "pretrain_bc_fraction",
        _sub("pretrain", "bc_minibatches", 2.5),
        r"pretrain\.bc_minibatches.*integer",
    ),
    (
        "pretrain_bc_scenarios_unknown",
        _sub("pretrain", "bc_scenarios", ["windy"]),
        r"pretrain\.bc_scenarios\.0",
    ),
    (
        "pretrain_bc_scenarios_empty",
        _sub("pretrain", "bc_scenarios", []),
        r"pretrain\.bc_scenarios",
    ),
    (
        "pretrain_bc_lr_zero",
        _sub("pretrain", "bc_learning_rate", 0.0),
        r"pretrain\.bc_learning_rate.*\(0, 1\]",
    ),
    (
        "pretrain_floor_unknown_scenario",
        _sub("pretrain", "teacher_r_floor", {"windy": 2.0}),
        r"pretrain\.teacher_r_floor",
    ),
    (
        "pretrain_floor_above_range",
        _sub("pretrain", "teacher_r_floor", {"noise_bursts": 9.0}),
        r"pretrain\.teacher_r_floor\.noise_bursts.*\[-2, 7\]",
    ),
    (
        "pretrain_floor_text",
        _sub("pretrain", "teacher_r_floor", {"noise_bursts": "high"}),
        r"pretrain\.teacher_r_floor\.noise_bursts.*number",
    ),
    ("pretrain_unknown", _sub("pretrain", "stepz", 1), "pretrain.stepz is unknown"),
]

GOOD_TEXT = HYPERPARAMS.read_text(encoding="utf-8")
#: Text-level faults: (case, the file's text or bytes, the message's problem).
TEXT_FAULTS: list[tuple[str, str | bytes, str]] = [
    ("empty", "", "empty"),
    ("blank", "  \n\t\n", "empty"),
    ("truncated", GOOD_TEXT[: len(GOOD_TEXT) // 2], "not valid JSON"),
    ("one_brace", "{", "not valid JSON"),
    ("trailing_comma", '{"version": 5, "scenarios": {},}', "not valid JSON"),
    ("binary", np.random.default_rng(20).bytes(256), "not UTF-8 text|not valid JSON"),
    ("gamma_nan", GOOD_TEXT.replace('"gamma": 0.7', '"gamma": NaN'), "gamma.*NaN"),
    (
        "learning_rate_infinity",
        GOOD_TEXT.replace('"learning_rate": 0.0003', '"learning_rate": Infinity'),
        "learning_rate.*Infinity",
    ),
    (
        "clip_range_overflow",
        GOOD_TEXT.replace('"clip_range": 0.2', '"clip_range": 1e400'),
        "clip_range.*1e400",
    ),
    (
        "duplicate_key",
        GOOD_TEXT.replace('"gamma": 0.7', '"gamma": 0.7, "gamma": 2.0'),
        "gamma.*twice",
    ),
    ("nested_too_deeply", "[" * 100_000 + "]" * 100_000, "nested too deeply"),
    *[
        (
            f"nested_{n}_deep",
            '{"version": 1, "scenarios": {"nonstationary": ' + "[" * n + "]" * n + "}}",
            "nested too deeply|must be an object",
        )
        for n in (900, 990, 1500)
    ],
    (
        "a_4301_digit_integer",
        GOOD_TEXT.replace('"n_envs": 8', '"n_envs": ' + "9" * 4301),
        "not valid JSON",
    ),
    ("larger_than_1_mib", " " * 2**20 + "{}", "larger than"),
]


def _write(tmp_path: Path, case: str, data: str | bytes) -> Path:
    path = tmp_path / f"{case}.json"
    if isinstance(data, bytes):
        path.write_bytes(data)
    else:
        path.write_text(data, encoding="utf-8")
    return path


def _refused(path: Path, problem: str) -> str:
    with pytest.raises(HyperparameterError) as info:
        load_hyperparams("nonstationary", path)
    return assert_one_line_error(info, str(path), patterns=(problem,))


@pytest.mark.parametrize(("case", "mutate", "problem"), DOC_FAULTS, ids=[c[0] for c in DOC_FAULTS])
def test_invalid_documents_are_refused(tmp_path, case, mutate, problem):
    path = _write(tmp_path, case, json.dumps(mutate(copy.deepcopy(SHIPPED))))
    _refused(path, problem)


@pytest.mark.parametrize(("case", "data", "problem"), TEXT_FAULTS, ids=[c[0] for c in TEXT_FAULTS])
def test_unreadable_text_is_refused(tmp_path, case, data, problem):
    _refused(_write(tmp_path, case, data), problem)


def test_missing_file_directory_and_device(tmp_path):
    _refused(tmp_path / "missing.json", "no such file")
    (tmp_path / "dir.json").mkdir()
    _refused(tmp_path / "dir.json", "directory")
    _refused(Path("/dev/zero"), "not a regular file")  # reading it would never end


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("gamma", 1.0),
        ("gae_lambda", 0.0),
        ("gae_lambda", 1.0),
        ("learning_rate", "lin_3e-4"),
        ("learning_rate", 1),
        ("batch_size", 2),
        ("net_arch", []),
        ("clip_range", 1.0),
        ("ent_coef", 0),
        ("ent_coef", 1.0),
        ("learning_rate", 1.0),
        ("log_std_init", -20.0),
        ("vec_env", "dummy"),
        ("prefetch", False),
        ("train_scenario", "nonstationary"),
    ],
)
def test_values_at_the_bounds_are_accepted(tmp_path, key, value):
    path = _write(tmp_path, "ok", json.dumps(_hp(key, value)(copy.deepcopy(SHIPPED))))
    assert load_hyperparams("nonstationary", path).to_entry()[key] == value


def test_the_shipped_file_loads_unchanged(tmp_path):
    shipped = load_hyperparams("nonstationary")
    assert shipped.version == SHIPPED["version"]
    entry = shipped.to_entry()  # the file's values, and the defaults of what it leaves out
    assert {k: entry[k] for k in HP if k != "pretrain"} == {
        k: v for k, v in HP.items() if k != "pretrain"
    }
    assert {k: entry["pretrain"][k] for k in HP["pretrain"]} == HP["pretrain"]
    bom = _write(tmp_path, "bom", "\ufeff" + GOOD_TEXT)  # as some editors save it
    assert load_hyperparams("nonstationary", bom) == load_hyperparams("nonstationary")


def test_the_schema_names_what_the_code_knows():
    """The schema is valid JSON Schema, its enumerations are the code's, and it requires every
    key training reads without a default."""
    jsonschema.Draft202012Validator.check_schema(SCHEMA)
    scenario = SCHEMA["$defs"]["PPOHyperparams"]
    assert set(scenario["properties"]["vec_env"]["enum"]) == set(VEC_ENVS)
    assert scenario["properties"]["train_scenario"]["enum"] == list(SCENARIOS + TRAINING_SCENARIOS)
    pretrain = SCHEMA["$defs"]["Pretrain"]["properties"]
    assert pretrain["bc_scenarios"]["items"]["enum"] == list(SCENARIOS + TRAINING_SCENARIOS)
    assert pretrain["teacher_r_floor"]["propertyNames"]["enum"] == [
        s for s in SCENARIOS + TRAINING_SCENARIOS if s != "suite"
    ]
    # hyperparameters per evaluated scenario, and for the general policy validated on the suite
    assert SCHEMA["properties"]["scenarios"]["propertyNames"]["enum"] == [*SCENARIOS, "suite"]
    read = set(_ppo_kwargs(load_hyperparams("nonstationary"))) - {"policy_kwargs"} | {
        "net_arch",
        "n_envs",
        "normalize_reward",
        "eval_every",
        "eval_episodes",
        "env_kwargs",
    }
    assert read <= set(scenario["required"])
    # the shipped file is valid under the schema an editor reads
    jsonschema.Draft202012Validator(SCHEMA).validate(SHIPPED)


@pytest.mark.parametrize("case", ["gamma_two", "gamma_nan", "a_list", "missing_net_arch"])
def test_cli_train_with_bad_hyperparams_exits_2_before_training(tmp_path, capsys, case):
    faults = {c: t for c, t, _ in TEXT_FAULTS}
    mutations = {c: m for c, m, _ in DOC_FAULTS}
    text = faults.get(case) or json.dumps(mutations[case](copy.deepcopy(SHIPPED)))
    path = _write(tmp_path, case, text)
    out = tmp_path / "out"
    args = [
        "train",
        "--hyperparams",
        str(path),
        "--quick",
        "--timesteps",
        "64",
        "--out",
        str(out),
        "--quiet",
    ]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and str(path) in err and "Traceback" not in err
    assert not out.exists()


JSON_VALUES = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(10**20), 10**20)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=8),
    lambda inner: (
        st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=5), inner, max_size=3)
    ),
    max_leaves=6,
)


@settings(
    max_examples=examples(300),
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(key=st.sampled_from(sorted(HP)), value=JSON_VALUES)
def test_any_value_for_any_key_loads_or_names_the_key(tmp_path, key, value):
    """Any JSON value in place of a hyperparameter: either it is accepted (and is then what
    the file says) or a one-line HyperparameterError names that hyperparameter."""
    path = _write(tmp_path, "fuzz", json.dumps(_hp(key, value)(copy.deepcopy(SHIPPED))))
    try:
        hp = load_hyperparams("nonstationary", path)
    except HyperparameterError as e:
        assert_one_line_error(e, key)
        return
    assert hp.to_entry()[key] == value


def test_the_committed_schemas_are_the_ones_made_from_the_models():
    """``ppo.schema.json`` and ``learners.schema.json`` are made from the models (``python -m
    agents.training.schemas`` rewrites them): a field changed in a model alone fails
    here; and each is valid JSON Schema that the shipped file passes."""
    from agents.training.schemas import schema_text, schemas

    made = schemas()
    assert [p.name for p in made] == ["ppo.schema.json", "learners.schema.json"]
    for path, schema in made.items():
        assert path.read_text(encoding="utf-8") == schema_text(schema), path.name
        jsonschema.Draft202012Validator.check_schema(schema)
        shipped = json.loads(path.with_name(path.name.replace(".schema", "")).read_text())
        jsonschema.Draft202012Validator(schema).validate(shipped)


def test_the_model_holds_the_file_and_the_defaults():
    """The shipped entries load to the same values; what a file leaves out takes the
    model's default, the one training uses."""
    from agents.training.hyperparameters import PPOHyperparams, Pretrain

    for scenario, entry in SHIPPED["scenarios"].items():
        hp = load_hyperparams(scenario)
        assert hp == PPOHyperparams.from_entry(entry, SHIPPED["version"])
        for key, value in entry.items():
            got = hp.to_entry()[key]
            assert got == value if key != "pretrain" else {k: got[k] for k in value} == value
    left_out = ("vec_env", "prefetch", "pretrain", "train_scenario")
    lean = {k: v for k, v in HP.items() if k not in left_out}
    hp = PPOHyperparams.from_entry(lean)
    assert (hp.vec_env, hp.prefetch, hp.select_by, hp.pretrain, hp.train_scenario) == (
        "batched",
        True,
        "rmse",
        None,
        None,
    )
    assert "pretrain" not in hp.to_entry() and "train_scenario" not in hp.to_entry()
    spec = Pretrain(steps=1, epochs=1)
    assert (spec.demonstrator, spec.dagger_rounds, spec.threshold_nt) == (
        "innovation_detector",
        1,
        20.0,
    )


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"gamma": 1.5}, r"^gamma must be a number in \(0, 1\], got 1\.5$"),
        ({"n_envs": 0}, r"^n_envs must be an integer ≥ 1 and ≤ 256"),
        ({"learning_rate": "cos_1"}, r"^learning_rate must be a number in \(0, 1\], or"),
        ({"net_arch": [64, 0]}, r"^net_arch\.1 must be an integer ≥ 1"),
        ({"vec_env": "subproc"}, r"^vec_env must be batched or dummy"),
        ({"env_kwargs": {"split_q": 3}}, r"^env_kwargs: split_q must be true or false"),
        ({"env_kwargs": {"preset": "windy"}}, r"^env_kwargs: unknown preset 'windy'"),
        ({"pretrain": {"steps": 0}}, r"^pretrain\.steps must be an integer ≥ 1"),
    ],
)
def test_a_bad_value_is_a_one_line_config_error_naming_the_field(change, message):
    from pydantic import ValidationError

    from aeromag_env.errors import ConfigError

    hp = load_hyperparams("nonstationary")
    with pytest.raises(ConfigError, match=message) as info:
        hp.with_values(**change)
    assert "\n" not in str(info.value)
    with pytest.raises(ValidationError, match="frozen"):
        hp.gamma = 0.5  # type: ignore[misc]


def test_the_model_is_keyword_only():
    from agents.training.hyperparameters import PPOHyperparams

    with pytest.raises(TypeError):
        PPOHyperparams(2, 64)  # type: ignore[misc]
