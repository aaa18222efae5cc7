"""PPO's hyperparameters as a frozen, validated dataclass, and the JSON Schema made from it.

Each field of :class:`PPOHyperparams` (one scenario's entry of
``agents/training/hyperparams/ppo.json``)
and of :class:`Pretrain` (its ``pretrain`` object) carries its title, what it allows and its
JSON Schema constraints; its default, where it has one, is the one training uses. From these
:func:`ppo_schema` makes ``agents/training/hyperparams/ppo.schema.json`` (``python -m
agents.training.ppo_hyperparams`` rewrites it; a test checks that the committed file is the
generated one), which :mod:`agents.training.hyperparams_file` checks a file against, and
``__post_init__``
checks
the same constraints on a value built in Python: a one-line
:class:`~aeromag_env.errors.ConfigError` naming the field.
"""

from __future__ import annotations

import copy
import json
import sys
from collections.abc import Mapping
from dataclasses import MISSING, dataclass, field, fields
from pathlib import Path
from types import MappingProxyType
from typing import Any

from aeromag_env.configs import from_dict
from aeromag_env.environment.env import EnvConfig
from aeromag_env.environment.scenarios import SCENARIOS, TRAINING_SCENARIOS
from aeromag_env.errors import ConfigError
from agents.training.hyperparams_file import SCHEMA, schema_problem

#: Every scenario a policy may be trained on.
_TRAINABLE = [*SCENARIOS, *TRAINING_SCENARIOS]
#: The scenarios with an entry: those evaluated, and ``suite`` (the general policy).
_ENTRIES = [*SCENARIOS, "suite"]
#: The fields stable-baselines3's PPO takes as they are (``agents.training.ppo`` passes them to
#: ``PPO``,
#: ``agents.training.zoo`` writes them into the RL Zoo file with ``n_envs``).
SB3_PPO_KEYS = (
    "n_steps",
    "batch_size",
    "n_epochs",
    "learning_rate",
    "gamma",
    "gae_lambda",
    "ent_coef",
    "clip_range",
)
#: A learning rate falling linearly to 0 from a positive number (RL Zoo's notation).
_LIN = "^lin_(?=[0.]*[1-9])([0-9]+[.]?[0-9]*|[.][0-9]+)([eE][-+]?[0-9]+)?$"


def _hp(title: str, allowed: str, schema: dict[str, Any]) -> dict[str, Any]:
    """A hyperparameter field's metadata: its ``title``, what it ``allowed`` (the error says
    "must be …") and its JSON Schema constraints."""
    return {"title": title, "description": allowed, "schema": schema}


def _int(lo: int, hi: int) -> dict[str, Any]:
    return {"type": "integer", "minimum": lo, "maximum": hi}


def _names(names: list[str]) -> str:
    return "a scenario name: " + ", ".join(names)


@dataclass(frozen=True, kw_only=True)
class Pretrain:
    """Behaviour cloning of a demonstrator before PPO and, with ``bc_minibatches``, during it
    (:func:`agents.training.imitation.behaviour_clone`,
    :class:`agents.training.imitation.CloningTerm`)."""

    steps: int = field(
        metadata=_hp(
            "demonstration steps",
            "an integer ≥ 1 and ≤ 10000000 (held in memory; 50× the shipped 200000)",
            _int(1, 10_000_000),
        )
    )
    epochs: int = field(
        metadata=_hp("passes of Adam over them", "an integer ≥ 1 and ≤ 100", _int(1, 100))
    )
    dagger_rounds: int = field(
        default=1,
        metadata=_hp(
            "rounds of imitation (privileged demonstrator): the first follows the teacher, each "
            "later one follows the student so far and is labelled by the teacher (DAgger); every "
            "round refits on all rounds' data",
            "an integer ≥ 1 and ≤ 20",
            _int(1, 20),
        ),
    )
    demonstrator: str = field(
        default="innovation_detector",
        metadata=_hp(
            "the policy imitated",
            "innovation_detector (the default) or privileged (knows the truth; the student sees "
            "the observations only)",
            {"enum": ["innovation_detector", "privileged"]},
        ),
    )
    threshold_nt: float = field(
        default=20.0,
        metadata=_hp(
            "the detector's threshold [nT]",
            "a number > 0 [nT]",
            {"type": "number", "exclusiveMinimum": 0},
        ),
    )
    learning_rate: float = field(
        default=1e-3,
        metadata=_hp("Adam step size", "a number > 0", {"type": "number", "exclusiveMinimum": 0}),
    )
    bc_minibatches: int = field(
        default=0,
        metadata=_hp(
            "behaviour cloning kept on during PPO: minibatches of Adam on the actor toward "
            "the demonstrations after each PPO update (agents.training.imitation.CloningTerm); "
            "0 or "
            "absent: none",
            "an integer ≥ 0 and ≤ 1000",
            _int(0, 1000),
        ),
    )
    bc_scenarios: tuple[str, ...] | None = field(
        default=None,
        metadata=_hp(
            "the scenarios whose demonstrations the cloning kept on during PPO uses (a suite "
            "flight counts as the scenario drawn for it); absent: all",
            "a list of scenario names",
            {"type": "array", "minItems": 1, "items": {"enum": _TRAINABLE}},
        ),
    )
    teacher_r_floor: Mapping[str, float] | None = field(
        default=None,
        metadata=_hp(
            "the privileged teacher's floor on R per scenario: the log10 R scale (of R(0)) it "
            "never sets R below on flights of that scenario "
            "(agents.policies.baselines.PrivilegedPolicy, r_floor)",
            "an object of scenario names to numbers in [-2, 7] (the absolute R range)",
            {
                "type": "object",
                "propertyNames": {"enum": [s for s in _TRAINABLE if s != "suite"]},
                "additionalProperties": {
                    "title": "the log10 R scale floor",
                    "description": "a number in [-2, 7]",
                    "type": "number",
                    "minimum": -2,
                    "maximum": 7,
                },
            },
        ),
    )
    bc_learning_rate: float = field(
        default=1e-4,
        metadata=_hp(
            "Adam step size of the cloning kept on during PPO (default 0.0001)",
            "a number > 0",
            {"type": "number", "exclusiveMinimum": 0},
        ),
    )

    def __post_init__(self) -> None:
        if self.bc_scenarios is not None:
            object.__setattr__(self, "bc_scenarios", tuple(self.bc_scenarios))
        if self.teacher_r_floor is not None:
            object.__setattr__(
                self, "teacher_r_floor", MappingProxyType(dict(self.teacher_r_floor))
            )
        _check_fields(self, "pretrain.")


@dataclass(frozen=True, kw_only=True)
class PPOHyperparams:
    """One scenario's PPO hyperparameters (an entry of ``agents/training/hyperparams/ppo.json``),
    with the environment settings the policy is trained and evaluated with; ``version`` is the
    version of the file it was read from (0: not read from a file)."""

    train_scenario: str | None = field(
        default=None,
        metadata=_hp(
            "scenario of the training flights when it differs from the evaluated one",
            _names(_TRAINABLE),
            {"enum": _TRAINABLE},
        ),
    )
    n_envs: int = field(
        metadata=_hp(
            "training environments stepped together",
            "an integer ≥ 1 and ≤ 256 (each environment holds its flight and filter in memory)",
            _int(1, 256),
        )
    )
    vec_env: str = field(
        default="batched",
        metadata=_hp(
            "vectorisation of the training environments",
            "batched or dummy",
            {"enum": ["batched", "dummy"]},
        ),
    )
    prefetch: bool = field(
        default=True,
        metadata=_hp(
            "simulate the next flights in a worker process", "true or false", {"type": "boolean"}
        ),
    )
    n_steps: int = field(
        metadata=_hp(
            "steps per environment per rollout",
            "an integer ≥ 1 and ≤ 16384 (the rollout buffer holds n_envs × n_steps steps: at most "
            "4.2 million)",
            _int(1, 16384),
        )
    )
    batch_size: int = field(
        metadata=_hp(
            "minibatch size (stable-baselines3 needs more than 1)",
            "an integer ≥ 2 and ≤ 65536 (a minibatch's activations are held at once)",
            _int(2, 65536),
        )
    )
    n_epochs: int = field(
        metadata=_hp(
            "passes over each rollout",
            "an integer ≥ 1 and ≤ 100 (stable-baselines3's default is 10)",
            _int(1, 100),
        )
    )
    learning_rate: float | str = field(
        metadata=_hp(
            "Adam step size, constant or falling linearly to 0 (RL Zoo's lin_<number>)",
            'a number > 0, or "lin_<number > 0>"',
            {
                "anyOf": [
                    {"type": "number", "exclusiveMinimum": 0},
                    {"type": "string", "pattern": _LIN},
                ]
            },
        )
    )
    gamma: float = field(
        metadata=_hp(
            "discount factor",
            "a number in (0, 1]",
            {"type": "number", "exclusiveMinimum": 0, "maximum": 1},
        )
    )
    gae_lambda: float = field(
        metadata=_hp(
            "GAE bias-variance factor",
            "a number in [0, 1]",
            {"type": "number", "minimum": 0, "maximum": 1},
        )
    )
    ent_coef: float = field(
        metadata=_hp("entropy bonus", "a number ≥ 0", {"type": "number", "minimum": 0})
    )
    clip_range: float = field(
        metadata=_hp(
            "PPO's clipping of the probability ratio",
            "a number in (0, 1]",
            {"type": "number", "exclusiveMinimum": 0, "maximum": 1},
        )
    )
    net_arch: tuple[int, ...] = field(
        metadata=_hp(
            "units per hidden layer of the actor and the critic",
            "a list of at most 8 integers ≥ 1 and ≤ 1024",
            {
                "type": "array",
                "maxItems": 8,
                "items": {
                    "title": "units of a hidden layer",
                    "description": "an integer ≥ 1 and ≤ 1024 (the shipped networks have 64)",
                    **_int(1, 1024),
                },
            },
        )
    )
    normalize_reward: bool = field(
        metadata=_hp("VecNormalize's reward scaling", "true or false", {"type": "boolean"})
    )
    eval_every: int = field(
        metadata=_hp(
            "timesteps between validations",
            "an integer ≥ 1 and ≤ 1000000000 (aeromag train's largest --timesteps)",
            _int(1, 1_000_000_000),
        )
    )
    eval_episodes: int = field(
        metadata=_hp(
            "validation flights per validation",
            "an integer ≥ 1 and ≤ 10000 (aeromag evaluate's largest --episodes)",
            _int(1, 10_000),
        )
    )
    select_by: str = field(
        default="rmse",
        metadata=_hp(
            "how the best validated policy is chosen",
            "rmse (mean validation RMSE, the default), ratio_to_privileged (mean over the "
            "validation flights of the RMSE over the privileged policy's on the same flight) or "
            "worst_ratio_to_tuned_constant (the validation flights split over the suite's "
            "scenarios; the worst scenario's mean ratio of the RMSE to the tuned constant's on the "
            "same flights)",
            {"enum": ["rmse", "ratio_to_privileged", "worst_ratio_to_tuned_constant"]},
        ),
    )
    log_std_init: float = field(
        default=0.0,
        metadata=_hp(
            "initial log std of the Gaussian policy (stable-baselines3's SAC bounds it the same)",
            "a number in [-20, 2]",
            {"type": "number", "minimum": -20, "maximum": 2},
        ),
    )
    env_kwargs: Mapping[str, Any] = field(
        metadata=_hp(
            "the environment settings (aeromag_env.environment.env.EnvConfig fields)",
            "an object of EnvConfig fields",
            {"type": "object"},
        )
    )
    pretrain: Pretrain | None = field(
        default=None,
        metadata=_hp(
            "behaviour cloning of a demonstrator before PPO "
            "(agents.training.imitation.behaviour_clone) "
            "and, with bc_minibatches, during it",
            "an object with steps, epochs and optional demonstrator, dagger_rounds, threshold_nt, "
            "learning_rate, bc_minibatches, bc_scenarios, bc_learning_rate, teacher_r_floor",
            {},
        ),
    )
    version: int = field(default=0, metadata={"schema": None})

    def __post_init__(self) -> None:
        object.__setattr__(self, "net_arch", tuple(self.net_arch))
        object.__setattr__(
            self, "env_kwargs", MappingProxyType(copy.deepcopy(dict(self.env_kwargs)))
        )
        if isinstance(self.pretrain, Mapping):
            object.__setattr__(self, "pretrain", _built(Pretrain, self.pretrain, "pretrain."))
        if not (self.pretrain is None or isinstance(self.pretrain, Pretrain)):
            raise ConfigError(f"pretrain: must be an object, got {type(self.pretrain).__name__}")
        _check_fields(self, "")
        try:
            from_dict(EnvConfig, dict(self.env_kwargs))
        except ConfigError as e:
            raise ConfigError(f"env_kwargs: {e}") from None

    @classmethod
    def from_entry(cls, entry: Mapping[str, Any], version: int = 0) -> PPOHyperparams:
        """The hyperparameters of a scenario's entry of a hyperparameter file (a JSON object;
        one-line ConfigError for an unknown key or a bad value)."""
        return _built(cls, {**entry, "version": version}, "")

    def with_values(self, **changes: Any) -> PPOHyperparams:
        """A copy with ``changes`` (a ``pretrain`` change is a dict merged into its own)."""
        if isinstance(changes.get("pretrain"), Mapping) and self.pretrain is not None:
            merged = {**_values(self.pretrain), **changes["pretrain"]}
            changes["pretrain"] = _built(Pretrain, merged, "pretrain.")
        return _built(PPOHyperparams, {**_values(self), **changes}, "")

    def to_entry(self) -> dict[str, Any]:
        """The entry as JSON values (defaults included; not ``version``; an optional field that
        is None left out, as a file says it)."""
        return _entry(self)


def _values(obj: Any) -> dict[str, Any]:
    """The fields of the dataclass ``obj`` by name (not copied)."""
    return {f.name: getattr(obj, f.name) for f in fields(obj)}


def _built(cls: Any, values: Mapping[str, Any], prefix: str) -> Any:
    """``cls(**values)``; a one-line ConfigError for a key that is no field of ``cls``."""
    unknown = sorted(set(values) - {f.name for f in fields(cls)})
    if unknown:
        valid = ", ".join(f.name for f in fields(cls) if f.name != "version")
        raise ConfigError(f"unknown hyperparameter(s) {prefix}{', '.join(unknown)}; valid: {valid}")
    return cls(**values)


def _check_fields(obj: Any, prefix: str) -> None:
    """ConfigError for the first field of ``obj`` outside its schema (None: a default none)."""
    for f in fields(obj):
        value, schema = getattr(obj, f.name), f.metadata.get("schema")
        if not schema or (value is None and f.default is None):
            continue
        problem = schema_problem(
            _jsonable(value), {"description": f.metadata["description"], **schema}
        )
        if problem is not None:
            where = ": " if problem.startswith("must") else "."  # net_arch.1: must …
            raise ConfigError(f"{prefix}{f.name}{where}{problem}")


def _entry(obj: Any) -> dict[str, Any]:
    """The fields of ``obj`` (a dataclass of this module) as JSON values, ``version`` and the
    optional fields that are None (absent) left out."""
    return {
        f.name: _jsonable(getattr(obj, f.name))
        for f in fields(obj)
        if f.metadata.get("schema") is not None
        and not (getattr(obj, f.name) is None and f.default is None)
    }


def _jsonable(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, Pretrain):
        return _entry(value)
    return value


def _properties(cls: type) -> dict[str, Any]:
    """The JSON Schema of an object whose keys are the fields of ``cls``."""
    props: dict[str, Any] = {}
    required = []
    for f in fields(cls):
        if f.metadata.get("schema") is None:
            continue
        props[f.name] = {
            "title": f.metadata["title"],
            "description": f.metadata["description"],
            **f.metadata["schema"],
        }
        if f.default is MISSING:
            required.append(f.name)
    return {
        "type": "object",
        "required": required,
        "additionalProperties": False,
        "properties": props,
    }


def ppo_schema() -> dict[str, Any]:
    """The JSON Schema of a hyperparameter file, made from :class:`PPOHyperparams`."""
    scenario = {
        "title": "the hyperparameters of one scenario",
        "description": "an object of hyperparameters",
        **_properties(PPOHyperparams),
    }
    scenario["properties"]["pretrain"].update(_properties(Pretrain))
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "PPO hyperparameters (agents/training/hyperparams/ppo.json)",
        "description": "a JSON object with version, scenarios and an optional comment",
        "type": "object",
        "required": ["version", "scenarios"],
        "additionalProperties": False,
        "properties": {
            "version": {
                "title": "version of the table",
                "description": "an integer ≥ 1",
                "type": "integer",
                "minimum": 1,
            },
            "comment": {
                "title": "what the table is for",
                "description": "text",
                "type": "string",
            },
            "scenarios": {
                "title": "hyperparameters per evaluated scenario",
                "description": "an object: scenario name → its hyperparameters",
                "type": "object",
                "propertyNames": {
                    "description": _names(_ENTRIES).replace(
                        ", suite", ", or suite (the general policy)"
                    ),
                    "enum": _ENTRIES,
                },
                "additionalProperties": {"$ref": "#/$defs/scenario"},
            },
        },
        "$defs": {"scenario": scenario},
    }


def schema_text() -> str:
    """:func:`ppo_schema` as the text of ``agents/training/hyperparams/ppo.schema.json``."""
    return json.dumps(ppo_schema(), indent=2, ensure_ascii=False) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Rewrite ``agents/training/hyperparams/ppo.schema.json`` from the dataclasses."""
    target = Path(argv[0]) if argv else SCHEMA
    target.write_text(schema_text(), encoding="utf-8")
    print(f"wrote {target}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
