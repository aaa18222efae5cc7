"""The learners' hyperparameter models (:mod:`agents.training.learner_hyperparameters`): their
fields are the algorithms' own keywords with the algorithms' defaults, a bad ``learners.json``
is one line naming the file and the field, the stored hyperparameters of every shipped run load
(the first version's flat environment keys through :mod:`aeromag_env.environment.legacy`), and
``--quick`` is one table for every learner."""

from __future__ import annotations

import copy
import inspect
import json
from pathlib import Path
from typing import Any

import pytest

from aeromag_env.environment.config import PRESETS, env_config
from aeromag_env.errors import HyperparameterError
from agents.training import LEARNERS
from agents.training import learners as learners_module
from agents.training.hyperparams_file import read_learners, stored_hyperparams
from agents.training.learner_hyperparameters import LEARNER_MODELS
from agents.training.learners import HYPERPARAMS, learner_hyperparams, sb3_keywords
from agents.training.quick import QUICK, quick_hyperparams, quick_learner
from tests._helpers import assert_one_line_error

pytest.importorskip("sb3_contrib")
DOCS = Path(__file__).resolve().parents[2] / "docs"
SHIPPED = json.loads(HYPERPARAMS.read_text(encoding="utf-8"))


def _policy_class(learner: str) -> Any:
    from sb3_contrib.ppo_recurrent.policies import RecurrentActorCriticPolicy
    from sb3_contrib.tqc.policies import TQCPolicy
    from stable_baselines3.sac.policies import SACPolicy

    classes = {"recurrent_ppo": RecurrentActorCriticPolicy, "sac": SACPolicy, "tqc": TQCPolicy}
    return classes[learner]


@pytest.mark.parametrize("learner", ["recurrent_ppo", "sac", "tqc"])
def test_the_models_fields_are_the_algorithms_keywords_with_their_defaults(learner):
    """Each ``algo`` field is a constructor parameter of the learner's algorithm, each
    ``policy_kwargs`` field one of its policy, and each default is the library's: a key a file
    leaves out (not passed) and the model's default agree."""
    model = LEARNER_MODELS[learner]
    for part, params in (
        ("algo", learners_module.constructor_parameters(learner)),
        ("policy_kwargs", inspect.signature(_policy_class(learner).__init__).parameters),
    ):
        fields = model.model_fields[part].annotation.model_fields  # type: ignore[union-attr]
        for name, info in fields.items():
            assert name in params, f"{learner}.{part}.{name} is no keyword of the library"
            assert info.default == params[name].default, f"{learner}.{part}.{name}"


def test_only_the_given_keys_reach_the_algorithm():
    hp = learner_hyperparams("sac")
    given = SHIPPED["learners"]["sac"]
    keywords = sb3_keywords(hp)
    assert keywords.pop("policy_kwargs") == {"net_arch": [64, 64]}
    assert keywords == given["algo"]


def _write(tmp_path: Path, table: dict[str, Any]) -> Path:
    path = tmp_path / "learners.json"
    path.write_text(json.dumps(table), encoding="utf-8")
    return path


def _entry(learner: str, key: str, value: Any) -> Any:
    def change(table: dict[str, Any]) -> None:
        *parents, last = key.split(".")
        target = table["learners"][learner]
        for part in parents:
            target = target.setdefault(part, {})
        target[last] = value

    return change


def _common(key: str, value: Any) -> Any:
    return lambda table: table["common"].__setitem__(key, value)


def _drop(learner: str, key: str) -> Any:
    return lambda table: table["learners"][learner].pop(key)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            _entry("sac", "algo.gamma", 2),
            r"learners\.sac\.algo\.gamma must be a number in \(0, 1\], got 2$",
        ),
        (
            _entry("tqc", "algo.batch_size", 1.5),
            r"learners\.tqc\.algo\.batch_size must be an integer",
        ),
        (_entry("sac", "algo.ent_coef", "often"), r"learners\.sac\.algo\.ent_coef must be .*auto"),
        (_entry("sac", "algo.gamme", 0.9), r"learners\.sac\.algo\.gamme is unknown; valid: "),
        (_entry("sac", "policy_kwargs.net_arch", [64, 0]), r"sac\.policy_kwargs\.net_arch\.1 must"),
        (_entry("recurrent_ppo", "algo.n_steps", None), r"recurrent_ppo\.algo\.n_steps .*null"),
        (_entry("cmaes", "algo.flights", 8), r"learners\.cmaes\.algo\.flights must be .*multiple"),
        (_drop("cmaes", "algo"), r"learners\.cmaes\.algo is missing"),
        (_drop("sac", "timesteps"), r"learners\.sac\.timesteps is missing"),
        (_common("eval_every", 0), r": common\.eval_every must be an integer ≥ 1"),
        (_common("n_env", 8), r": common\.n_env is unknown; valid: n_envs"),
        (_common("env_kwargs", {"preset": "windy"}), r": common\.env_kwargs: unknown preset"),
        (_entry("sac", "env_kwargs", {"extras": 1}), r"learners\.sac\.env_kwargs: extras must be"),
        (lambda t: t["learners"].__setitem__("dqn", {}), r": learners\.dqn is no valid name"),
        (lambda t: t.__setitem__("version", "4"), r": version must be an integer ≥ 1, got \"4\""),
    ],
)
def test_a_bad_learners_file_is_one_line_naming_the_file_and_the_field(tmp_path, change, message):
    """Every learner of the file is checked (a bad ``cmaes`` entry is refused whichever learner
    is asked for), and a value from ``common`` is named there."""
    table = copy.deepcopy(SHIPPED)
    change(table)
    path = _write(tmp_path, table)
    with pytest.raises(HyperparameterError) as info:
        learner_hyperparams("sac", path)
    assert_one_line_error(info, f"{path}: ", patterns=(message,))


def test_the_learners_file_round_trips_through_the_models(tmp_path):
    """What a run stores (``to_entry`` and the version) loads back to the same model."""
    for learner, hp in read_learners(HYPERPARAMS).items():
        stored = {"learner": learner, "hyperparams": {**hp.to_entry(), "version": hp.version}}
        back = stored_hyperparams(stored)
        assert type(back) is type(hp) and back.version == hp.version == SHIPPED["version"]
        assert back.model_dump(exclude={"comment"}) == hp.model_dump(exclude={"comment"})


def _stored_runs() -> list[tuple[str, dict[str, Any]]]:
    runs = [
        (f"docs/{name}/training.json", json.loads((DOCS / name / "training.json").read_text()))
        for name in ("ppo", "general")
    ]
    for run in json.loads((DOCS / "learners" / "runs.json").read_text())["runs"]:
        runs.append((f"docs/learners/runs.json {run['learner']} seed {run['seed']}", run))
    return runs


@pytest.mark.parametrize(("where", "run"), _stored_runs(), ids=[w for w, _ in _stored_runs()])
def test_the_hyperparameters_stored_by_the_shipped_runs_load(where, run):
    """The runs behind the shipped policies and the learners' page stored their hyperparameters
    as the files were then (``docs/ppo/training.json`` of version 5 with the first version's flat
    environment keys): each loads, its environment settings the preset they are."""
    hp = stored_hyperparams(run)
    assert hp.env_kwargs in ({"preset": "nonstationary"}, {"preset": "general"})
    assert hp.version == run["hyperparams"].get("version")


def test_the_legacy_settings_of_a_stored_run_are_the_preset():
    """docs/general/training.json's flat keys (what the general policy was trained with) are
    the ``general`` preset, field for field."""
    from aeromag_env.environment.legacy import upgrade

    flat = json.loads((DOCS / "general" / "training.json").read_text())["hyperparams"]["env_kwargs"]
    assert "extras" in flat and upgrade(flat) == {"preset": "general"}
    assert env_config(upgrade(flat)) == PRESETS["general"]


def test_quick_is_one_table_for_every_learner():
    """The sizes of a quick run of every learner come from :data:`QUICK` (quick.py); the
    learners' module keeps none of its own."""
    assert not any(name.startswith("QUICK") for name in vars(learners_module))
    for learner in LEARNERS[1:]:
        big = learner_hyperparams(learner).with_values(n_envs=64, timesteps=10**7)
        quick = quick_learner(big)
        assert {k: getattr(quick, k) for k in QUICK.learners} == dict(QUICK.learners)
        if learner == "cmaes":
            assert {k: getattr(quick.algo, k) for k in QUICK.cmaes} == dict(QUICK.cmaes)
        else:
            assert quick.algo == big.algo  # the algorithm's own settings are kept
    from agents.training.ppo import load_hyperparams

    quick_ppo = quick_hyperparams(load_hyperparams("suite"))
    assert {k: getattr(quick_ppo, k) for k in QUICK.ppo} == dict(QUICK.ppo)


def test_a_quick_run_clones_on_every_scenario_it_flew() -> None:
    """The suite entry clones only on some scenarios; a quick run's 256 demonstration steps fly
    parts of two flights, which may be of none of them (seed 2 of the suite was): quick clones
    on every scenario flown."""
    from agents.training import ppo
    from agents.training.hyperparams_file import read_ppo

    suite = read_ppo(ppo.HYPERPARAMS).scenarios["suite"]
    assert suite.pretrain is not None and suite.pretrain.bc_scenarios is not None
    quick = quick_hyperparams(suite).pretrain
    assert quick is not None and quick.bc_scenarios is None
    assert (quick.steps, quick.bc_minibatches) == (
        QUICK.pretrain["steps"],
        suite.pretrain.bc_minibatches,
    )
