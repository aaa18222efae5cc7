"""Every learner's hyperparameters as typed models, checked when built: the common scheme, and
PPO's.

One model per learner, the fields they share written once (here):

* :class:`LearnerSettings`, what every learner has: its environments (``n_envs``,
  ``prefetch``, ``env_kwargs``), the reward normalisation and the validation (``eval_every``,
  ``eval_episodes``, ``select_by``);
* :class:`PPOHyperparams` (one scenario's entry of ``agents/training/hyperparams/ppo.json``,
  with its :class:`Pretrain`);
* the four other learners (:mod:`agents.training.learner_hyperparameters`: an entry of
  ``learners.json`` under the file's ``common`` settings), each with its algorithm's ``algo``
  and, for the networks, ``policy_kwargs``; the PPO family's fields (``n_steps``, ``gamma``…)
  are the types declared here, in PPO and RecurrentPPO alike.

Each field carries its title, what it allows (its ``description``: an error says "must be
…") and its constraints; its default, where it has one, is the one training uses. A field
whose default is None is optional: absent means none, or in an ``algo`` or ``policy_kwargs``
the algorithm's own default; an explicit ``null`` is refused. ``env_kwargs`` are checked by
:class:`~aeromag_env.environment.config.EnvConfig` (an old file's flat keys are read by
:func:`aeromag_env.environment.legacy.upgrade`). Files are read by
:mod:`agents.training.hyperparams_file`, whose errors name the file and the field.

The JSON Schemas ``ppo.schema.json`` and ``learners.schema.json`` (for editors, and the
reference of the fields) are made from these models: ``python -m
agents.training.schemas`` rewrites them, and a test checks the committed files.

Why pydantic (v2): it validates a model from a file's JSON in one pass, strictly (8.0 is no
integer, 1 is no boolean) and with every error's location (``scenarios.suite.gamma``), and it
makes the JSON Schema from the same field declarations. The hand-written schema generator,
the schema validation by ``jsonschema`` and the dataclass's second check of the same ranges are
one declaration now. attrs with cattrs validates and structures as well, but makes no JSON
Schema: the generator would have stayed ours.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationError, field_validator
from pydantic.json_schema import GenerateJsonSchema, JsonSchemaValue
from pydantic_core import PydanticCustomError, core_schema
from typing_extensions import Self

from aeromag_env.configs import from_dict
from aeromag_env.environment.env import EnvConfig
from aeromag_env.environment.legacy import upgrade
from aeromag_env.environment.scenarios import SCENARIOS, TRAINING_SCENARIOS
from aeromag_env.errors import ConfigError
from agents.training.model_errors import problem

#: Every scenario a policy may be trained on.
_TRAINABLE = (*SCENARIOS, *TRAINING_SCENARIOS)
#: The scenarios with an entry in ``ppo.json``: those evaluated, and ``suite`` (the general
#: policy).
_ENTRIES = (*SCENARIOS, "suite")
#: A learning rate falling linearly to 0 from a positive number (RL Zoo's notation).
_LIN = "^lin_(?=[0.]*[1-9])([0-9]+[.]?[0-9]*|[.][0-9]+)([eE][-+]?[0-9]+)?$"
#: The fields stable-baselines3's PPO takes as they are (``agents.training.ppo`` passes them to
#: ``PPO``, ``agents.training.zoo`` writes them into the RL Zoo file with ``n_envs``).
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


@dataclass(frozen=True)
class OneOf:
    """A string that is one of ``names`` (a field's annotation: ``Annotated[str,
    OneOf(...)]``), described as ``what`` in the schema and in errors."""

    names: tuple[str, ...]
    what: str

    def __get_pydantic_core_schema__(self, source: Any, handler: Any) -> core_schema.CoreSchema:
        return core_schema.literal_schema(list(self.names))

    def __get_pydantic_json_schema__(self, schema: Any, handler: Any) -> JsonSchemaValue:
        return {
            **handler(schema),
            "description": f"{self.what}: {', '.join(self.names)}",
            "enum": list(self.names),
        }


def described(title: str, allowed: str, **constraints: Any) -> Any:
    """A field's title, what it allows (``must be …``) and its constraints."""
    return Field(title=title, description=allowed, **constraints)


def integer(lo: int, hi: int, title: str, allowed: str = "", **more: Any) -> Any:
    """An integer field in [lo, hi]: its title and what it allows (with ``allowed`` added)."""
    text = f"an integer ≥ {lo} and ≤ {hi}" + (f" ({allowed})" if allowed else "")
    return described(title, text, ge=lo, le=hi, **more)


# The fields the models share, each declared once.
NEnvs = Annotated[
    int,
    integer(1, 256, "training environments stepped together", "each holds a flight in memory"),
]
Timesteps = Annotated[
    int, integer(1, 10**9, "environment steps of a training run", "aeromag train's largest")
]
EvalEvery = Annotated[
    int,
    integer(1, 10**9, "timesteps between validations", "aeromag train's largest --timesteps"),
]
EvalEpisodes = Annotated[
    int,
    integer(
        1, 10_000, "validation flights per validation", "aeromag evaluate's largest --episodes"
    ),
]
SelectBy = Annotated[
    Literal["rmse", "ratio_to_privileged", "worst_ratio_to_tuned_constant"],
    described(
        "how the best validated policy is chosen",
        "rmse (mean validation RMSE, the default), ratio_to_privileged (mean over the "
        "validation flights of the RMSE over the privileged policy's on the same flight) or "
        "worst_ratio_to_tuned_constant (the validation flights split over the suite's "
        "scenarios; the worst scenario's mean ratio of the RMSE to the tuned constant's on the "
        "same flights)",
    ),
]
NSteps = Annotated[
    int,
    integer(
        1,
        16384,
        "steps per environment per rollout",
        "the rollout buffer holds n_envs × n_steps steps: at most 4.2 million",
    ),
]
BatchSize = Annotated[
    int,
    integer(
        2,
        65536,
        "minibatch size",
        "stable-baselines3 needs more than 1; a minibatch's activations are held at once",
    ),
]
NEpochs = Annotated[
    int, integer(1, 100, "passes over each rollout", "stable-baselines3's default is 10")
]
StepSize = Annotated[float, described("Adam step size", "a number in (0, 1]", gt=0, le=1)]
Gamma = Annotated[float, described("discount factor", "a number in (0, 1]", gt=0, le=1)]
GaeLambda = Annotated[
    float, described("GAE bias-variance factor", "a number in [0, 1]", ge=0, le=1)
]
EntCoef = Annotated[float, described("entropy bonus", "a number in [0, 1]", ge=0, le=1)]
ClipRange = Annotated[
    float, described("PPO's clipping of the probability ratio", "a number in (0, 1]", gt=0, le=1)
]
Units = Annotated[
    int, integer(1, 1024, "units of a hidden layer", "the shipped networks have 64", strict=True)
]
NetArch = Annotated[
    tuple[Units, ...],
    described(
        "units per hidden layer",
        "a list of at most 8 integers ≥ 1 and ≤ 1024",
        max_length=8,
        strict=False,  # a JSON list; its items stay strict
    ),
]
LogStdInit = Annotated[
    float,
    described(
        "initial log std of the Gaussian policy (stable-baselines3's SAC bounds it the same)",
        "a number in [-20, 2]",
        ge=-20,
        le=2,
    ),
]
Switch = Annotated[bool, described("a switch", "true or false")]


class Model(BaseModel):
    """Frozen, keyword-only, strict (no conversion of a value of another type), no unknown
    keys; an optional field (default None) is left out, never given as null."""

    model_config = ConfigDict(
        frozen=True, extra="forbid", strict=True, allow_inf_nan=False, regex_engine="python-re"
    )

    @field_validator("*", mode="before")
    @classmethod
    def _given(cls, value: Any) -> Any:
        if value is None:
            raise PydanticCustomError("null", "null is not a value; leave the key out")
        return value

    def with_values(self, **changes: Any) -> Self:
        """A checked copy with ``changes`` (a dict given for a field that is a model is
        merged into it: ``algo={"gamma": 0.9}`` changes that key only; None leaves an optional
        field out); a one-line ConfigError naming the field."""
        values = self.model_dump(exclude_unset=True)
        for key, value in changes.items():
            current = getattr(self, key, None)
            if isinstance(current, BaseModel) and isinstance(value, Mapping):
                value = _given({**current.model_dump(exclude_unset=True), **value})
            values[key] = value
        values = _given(values)
        built: Self = checked(type(self), values)
        for name, value in (self.__pydantic_private__ or {}).items():
            setattr(built, name, value)
        return built


class LearnerSettings(Model):
    """What every learner has: its training environments and its validation."""

    n_envs: NEnvs
    prefetch: bool = described(
        "simulate the next flights in a worker process", "true or false", default=True
    )
    normalize_reward: bool = described("VecNormalize's reward scaling", "true or false")
    eval_every: EvalEvery
    eval_episodes: EvalEpisodes
    select_by: SelectBy = "rmse"
    env_kwargs: dict[str, Any] = described(
        "the environment settings (aeromag_env.environment.config.EnvConfig: a preset and "
        'fields, e.g. {"preset": "general"})',
        "an object of EnvConfig fields",
    )

    @field_validator("env_kwargs")
    @classmethod
    def _environment(cls, value: dict[str, Any]) -> dict[str, Any]:
        try:
            settings = upgrade(value)  # an old file's flat keys, in today's terms
            from_dict(EnvConfig, settings)
        except ConfigError as e:
            raise ValueError(str(e)) from None
        return copy.deepcopy(settings)


class Pretrain(Model):
    """Behaviour cloning of a demonstrator before PPO and, with ``bc_minibatches``, during it
    (:func:`agents.training.imitation.behaviour_clone`,
    :class:`agents.training.imitation.CloningTerm`)."""

    model_config = ConfigDict(
        title="pretrain",
        json_schema_extra={
            "description": "an object with steps, epochs and optional demonstrator, "
            "dagger_rounds, threshold_nt, learning_rate, bc_minibatches, bc_scenarios, "
            "bc_learning_rate, teacher_r_floor"
        },
    )

    steps: int = integer(
        1, 10_000_000, "demonstration steps", "held in memory; 50× the shipped 200000"
    )
    epochs: int = integer(1, 100, "passes of Adam over them")
    dagger_rounds: int = integer(
        1,
        20,
        "rounds of imitation (privileged demonstrator): the first follows the teacher, each "
        "later one follows the student so far and is labelled by the teacher (DAgger); every "
        "round refits on all rounds' data",
        default=1,
    )
    demonstrator: Literal["innovation_detector", "privileged"] = described(
        "the policy imitated",
        "innovation_detector (the default) or privileged (knows the truth; the student sees "
        "the observations only)",
        default="innovation_detector",
    )
    threshold_nt: float = described(
        "the detector's threshold [nT]", "a number > 0 [nT]", gt=0, default=20.0
    )
    learning_rate: StepSize = 1e-3
    bc_minibatches: int = integer(
        0,
        1000,
        "behaviour cloning kept on during PPO: minibatches of Adam on the actor toward the "
        "demonstrations after each PPO update (agents.training.imitation.CloningTerm); 0: none",
        default=0,
    )
    bc_scenarios: (
        Annotated[
            tuple[Annotated[str, OneOf(_TRAINABLE, "a scenario name")], ...],
            described(
                "the scenarios whose demonstrations the cloning kept on during PPO uses (a suite "
                "flight counts as the scenario drawn for it); absent: all",
                "a list of one or more scenario names",
                min_length=1,
                strict=False,
            ),
        ]
        | None
    ) = None
    teacher_r_floor: (
        Annotated[
            dict[
                Annotated[str, OneOf(tuple(s for s in _TRAINABLE if s != "suite"), "a scenario")],
                Annotated[
                    float, described("the log10 R scale floor", "a number in [-2, 7]", ge=-2, le=7)
                ],
            ],
            described(
                "the privileged teacher's floor on R per scenario: the log10 R scale (of R(0)) it "
                "never sets R below on flights of that scenario "
                "(agents.policies.baselines.PrivilegedPolicy, r_floor)",
                "an object of scenario names to numbers in [-2, 7] (the absolute R range)",
            ),
        ]
        | None
    ) = None
    bc_learning_rate: Annotated[
        float,
        described(
            "Adam step size of the cloning kept on during PPO (default 0.0001)",
            "a number in (0, 1]",
            gt=0,
            le=1,
        ),
    ] = 1e-4


class PPOHyperparams(LearnerSettings):
    """One scenario's PPO hyperparameters (an entry of ``agents/training/hyperparams/ppo.json``),
    with the environment settings the policy is trained and evaluated with; :attr:`version` is
    the version of the file it was read from (0: not read from a file)."""

    model_config = ConfigDict(
        title="the hyperparameters of one scenario",
        json_schema_extra={"description": "an object of hyperparameters"},
    )

    train_scenario: (
        Annotated[
            str,
            OneOf(_TRAINABLE, "a scenario name"),
            Field(title="scenario of the training flights when it differs from the evaluated one"),
        ]
        | None
    ) = None
    vec_env: Literal["batched", "dummy"] = described(
        "vectorisation of the training environments", "batched or dummy", default="batched"
    )
    n_steps: NSteps
    batch_size: BatchSize
    n_epochs: NEpochs
    learning_rate: Annotated[
        Annotated[float, Field(gt=0, le=1)] | Annotated[str, Field(pattern=_LIN)],
        described(
            "Adam step size, constant or falling linearly to 0 (RL Zoo's lin_<number>)",
            'a number in (0, 1], or "lin_<number > 0>"',
        ),
    ]
    gamma: Gamma
    gae_lambda: GaeLambda
    ent_coef: EntCoef
    clip_range: ClipRange
    net_arch: NetArch = described(
        "units per hidden layer of the actor and the critic",
        "a list of at most 8 integers ≥ 1 and ≤ 1024",
    )
    log_std_init: LogStdInit = 0.0
    pretrain: Pretrain | None = described(
        "behaviour cloning of a demonstrator before PPO "
        "(agents.training.imitation.behaviour_clone) and, with bc_minibatches, during it",
        "an object with steps, epochs and optional demonstrator, dagger_rounds, threshold_nt, "
        "learning_rate, bc_minibatches, bc_scenarios, bc_learning_rate, teacher_r_floor",
        default=None,
    )
    _version: int = PrivateAttr(0)

    @property
    def version(self) -> int:
        """The version of the file the hyperparameters were read from (0: none)."""
        return self._version

    @classmethod
    def from_entry(cls, entry: Mapping[str, Any], version: int = 0) -> PPOHyperparams:
        """The hyperparameters of a scenario's entry of a hyperparameter file (a JSON object),
        read from a file of ``version``; a one-line ConfigError naming the field."""
        hp = checked(cls, entry)
        hp._version = version
        return hp

    def to_entry(self) -> dict[str, Any]:
        """The entry as JSON values (the defaults included; an optional field that is None
        left out, as a file says it)."""
        return self.model_dump(mode="json", exclude_none=True)


class PPOFile(Model):
    """The layout of ``ppo.json``."""

    model_config = ConfigDict(
        title="PPO hyperparameters (agents/training/hyperparams/ppo.json)",
        json_schema_extra={
            "description": "a JSON object with version, scenarios and an optional comment"
        },
    )

    version: int = described("version of the table", "an integer ≥ 1", ge=1)
    comment: Annotated[str, described("what the table is for", "text")] | None = None
    scenarios: dict[
        Annotated[str, OneOf(_ENTRIES, "a scenario name, or suite (the general policy)")],
        PPOHyperparams,
    ] = described(
        "hyperparameters per evaluated scenario", "an object: scenario name → its hyperparameters"
    )


def _given(values: dict[str, Any]) -> dict[str, Any]:
    """``values`` without the keys whose value is None (absent)."""
    return {k: v for k, v in values.items() if v is not None}


def checked(cls: type[Any], values: Mapping[str, Any]) -> Any:
    """``cls`` (a hyperparameter model) made from ``values``; a one-line ConfigError naming the
    field (:func:`agents.training.model_errors.problem`)."""
    try:
        return cls.model_validate(dict(values))
    except ValidationError as e:
        raise ConfigError(problem(e, values, model_schema(cls))) from None


# The JSON Schemas.
class SchemaGenerator(GenerateJsonSchema):
    """pydantic's JSON Schema of the models, as the files say them: an optional field is its
    type (null is no value), without pydantic's generated titles or a null default."""

    def nullable_schema(self, schema: core_schema.NullableSchema) -> JsonSchemaValue:
        return self.generate_inner(schema["schema"])

    def default_schema(self, schema: core_schema.WithDefaultSchema) -> JsonSchemaValue:
        value = super().default_schema(schema)
        if value.get("default", 0) is None:
            value.pop("default")
        return value

    def field_title_should_be_set(self, schema: Any) -> bool:
        return False


def model_schema(cls: type[BaseModel]) -> dict[str, Any]:
    """The JSON Schema of the model ``cls``."""
    return cls.model_json_schema(schema_generator=SchemaGenerator)


def ppo_schema() -> dict[str, Any]:
    """The JSON Schema of ``ppo.json``, made from :class:`PPOFile`."""
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", **model_schema(PPOFile)}
