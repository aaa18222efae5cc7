"""The hyperparameters of the learners beside PPO (``learners.json``), as typed models.

Each learner's entry of ``agents/training/hyperparams/learners.json``, under the file's
``common`` settings, is a model: :class:`RecurrentPPOHyperparams`, :class:`SACHyperparams`,
:class:`TQCHyperparams`, :class:`CMAESHyperparams`. They share every learner's settings
(:class:`~agents.training.hyperparameters.LearnerSettings`) and add the training budget
(``timesteps``), the algorithm's constructor keywords (``algo``) and its policy's
(``policy_kwargs``). The PPO family's fields are PPO's own types
(:mod:`agents.training.hyperparameters`). The defaults of ``algo`` and ``policy_kwargs`` are
the algorithm's (a test holds them to stable-baselines3's): the keys a file leaves out are
not passed, so the algorithm's own default applies.
"""

from __future__ import annotations

from typing import Annotated, Any, ClassVar

from pydantic import BaseModel, ConfigDict, Field
from pydantic.json_schema import models_json_schema

from aeromag_env.environment.ids import SUITE
from agents.training.hyperparameters import (
    BatchSize,
    ClipRange,
    EntCoef,
    GaeLambda,
    Gamma,
    LearnerSettings,
    LogStdInit,
    Model,
    NEpochs,
    NetArch,
    NSteps,
    OneOf,
    SchemaGenerator,
    StepSize,
    Switch,
    Timesteps,
    described,
    integer,
    model_schema,
)

#: SAC's learnt entropy coefficient, from 1 or from a positive number.
_AUTO = "^auto(_(?=[0.]*[1-9])([0-9]+[.]?[0-9]*|[.][0-9]+)([eE][-+]?[0-9]+)?)?$"


def _about(title: str) -> ConfigDict:
    """A model's title in the schema, and what a value of it must be: an object of them."""
    return ConfigDict(title=title, json_schema_extra={"description": f"an object of {title}"})


class RecurrentPPOAlgo(Model):
    """sb3-contrib's RecurrentPPO constructor keywords (the same types as PPO's)."""

    model_config = _about("RecurrentPPO's constructor keywords")

    n_steps: NSteps = 128
    batch_size: BatchSize = 128
    n_epochs: NEpochs = 10
    learning_rate: StepSize = 3e-4
    gamma: Gamma = 0.99
    gae_lambda: GaeLambda = 0.95
    ent_coef: EntCoef = 0.0
    clip_range: ClipRange = 0.2
    clip_range_vf: float | None = described(
        "clipping of the value function", "a number in (0, 10]", gt=0, le=10, default=None
    )
    normalize_advantage: Switch = True
    vf_coef: float = described("value loss weight", "a number in [0, 10]", ge=0, le=10, default=0.5)
    max_grad_norm: float = described(
        "gradient clipping", "a number in (0, 1000]", gt=0, le=1000, default=0.5
    )
    target_kl: float | None = described(
        "early stop at this KL divergence", "a number in (0, 10]", gt=0, le=10, default=None
    )
    use_sde: Switch = False
    sde_sample_freq: int = integer(
        -1, 10**6, "steps between noise samples of gSDE", "-1: per rollout", default=-1
    )


#: SAC's and TQC's entropy coefficient: a number, or learnt.
EntCoefOffPolicy = Annotated[
    Annotated[float, Field(ge=0, le=1)] | Annotated[str, Field(pattern=_AUTO)],
    described(
        "entropy coefficient",
        'a number in [0, 1], "auto" (learnt) or "auto_<number > 0>" (learnt from it)',
    ),
]


class SACAlgo(Model):
    """stable-baselines3's SAC constructor keywords."""

    model_config = _about("SAC's constructor keywords")

    learning_rate: StepSize = 3e-4
    buffer_size: int = integer(1, 10**7, "replay buffer size", "held in memory", default=1_000_000)
    learning_starts: int = integer(0, 10**9, "steps of random actions before learning", default=100)
    batch_size: int = integer(1, 65536, "minibatch size", default=256)
    tau: float = described("soft update rate", "a number in (0, 1]", gt=0, le=1, default=0.005)
    gamma: Gamma = 0.99
    train_freq: int = integer(1, 10**6, "environment steps between updates", default=1)
    gradient_steps: int = integer(1, 1000, "gradient steps per update", default=1)
    n_steps: int = integer(1, 1000, "steps of the n-step return", default=1)
    ent_coef: EntCoefOffPolicy = "auto"
    target_update_interval: int = integer(
        1, 10**6, "updates between target network updates", default=1
    )
    target_entropy: Annotated[
        float | Annotated[str, Field(pattern="^auto$")],
        described("target entropy", 'a number or "auto"'),
    ] = "auto"
    use_sde: Switch = False
    sde_sample_freq: int = integer(
        -1, 10**6, "steps between noise samples of gSDE", "-1: per rollout", default=-1
    )
    use_sde_at_warmup: Switch = False
    optimize_memory_usage: Switch = False


class TQCAlgo(SACAlgo):
    """sb3-contrib's TQC constructor keywords: SAC's and the quantiles dropped."""

    model_config = _about("TQC's constructor keywords")

    top_quantiles_to_drop_per_net: int = integer(
        0, 100, "top quantiles dropped per critic", default=2
    )


class CMAESAlgo(Model):
    """The CMA-ES search's sizes (:func:`agents.training.learners.run_learner`)."""

    model_config = _about("CMA-ES's settings")

    popsize: int = integer(2, 1000, "candidates per generation")
    sigma0: float = described(
        "initial step of the search over the rule's weights", "a number in (0, 10]", gt=0, le=10
    )
    flights: Annotated[
        int,
        integer(
            len(SUITE),
            100 * len(SUITE),
            "training flights per generation, as many of each scenario of the suite",
            f"a multiple of the suite's {len(SUITE)} scenarios",
            multiple_of=len(SUITE),
        ),
    ]
    normalisation_flights: int = integer(
        1, 1000, "training flights that fix the observation normalisation"
    )


class NetworkKwargs(Model):
    """The network of SAC's actor and critics (stable-baselines3's ``SACPolicy``)."""

    model_config = _about("SAC's policy keywords")

    net_arch: NetArch | None = None
    log_std_init: LogStdInit = -3.0
    n_critics: int = integer(1, 10, "critics", default=2)


class TQCNetworkKwargs(NetworkKwargs):
    """TQC's network: SAC's and the quantiles per critic."""

    model_config = _about("TQC's policy keywords")

    n_quantiles: int = integer(1, 1000, "quantiles per critic", default=25)


class RecurrentNetworkKwargs(Model):
    """RecurrentPPO's network: an LSTM before the actor's (and the critic's) layers."""

    model_config = _about("RecurrentPPO's policy keywords")

    net_arch: NetArch | None = None
    log_std_init: LogStdInit = 0.0
    lstm_hidden_size: int = integer(1, 1024, "units of the LSTM", default=256)
    n_lstm_layers: int = integer(1, 8, "LSTM layers", default=1)
    shared_lstm: Switch = False
    enable_critic_lstm: Switch = True


class _LearnerEntry(LearnerSettings):
    """A learner of ``learners.json``: the common settings, its training budget, its comment."""

    #: The learner's name in ``learners.json`` and on the command line.
    learner: ClassVar[str]
    timesteps: Timesteps
    comment: Annotated[str, described("what the entry is and why", "text")] | None = None
    _version: int | None = None

    @property
    def version(self) -> int | None:
        """The version of the file the hyperparameters were read from (None: none)."""
        return self._version

    def to_entry(self) -> dict[str, Any]:
        """The settings as the file gives them (the common ones under the entry's) as JSON
        values, without the comment: the keys given only (an absent ``algo`` key is the
        algorithm's default)."""
        return self.model_dump(mode="json", exclude_unset=True, exclude={"comment"})


class RecurrentPPOHyperparams(_LearnerEntry):
    """sb3-contrib's RecurrentPPO (an LSTM before the actor's layers), from scratch."""

    learner: ClassVar[str] = "recurrent_ppo"
    algo: RecurrentPPOAlgo = RecurrentPPOAlgo()
    policy_kwargs: RecurrentNetworkKwargs = RecurrentNetworkKwargs()


class SACHyperparams(_LearnerEntry):
    """stable-baselines3's SAC, from scratch."""

    learner: ClassVar[str] = "sac"
    algo: SACAlgo = SACAlgo()
    policy_kwargs: NetworkKwargs = NetworkKwargs()


class TQCHyperparams(_LearnerEntry):
    """sb3-contrib's TQC, from scratch."""

    learner: ClassVar[str] = "tqc"
    algo: TQCAlgo = TQCAlgo()
    policy_kwargs: TQCNetworkKwargs = TQCNetworkKwargs()


class CMAESHyperparams(_LearnerEntry):
    """CMA-ES over a linear rule (the ``cma`` package)."""

    learner: ClassVar[str] = "cmaes"
    algo: CMAESAlgo


#: The hyperparameters of a stable-baselines3 learner, and of any learner of ``learners.json``.
SB3Hyperparams = RecurrentPPOHyperparams | SACHyperparams | TQCHyperparams
LearnerHyperparams = SB3Hyperparams | CMAESHyperparams
#: The model of each learner of ``learners.json`` (PPO's is
#: :class:`~agents.training.hyperparameters.PPOHyperparams`).
LEARNER_MODELS: dict[str, type[LearnerHyperparams]] = {
    m.learner: m
    for m in (RecurrentPPOHyperparams, SACHyperparams, TQCHyperparams, CMAESHyperparams)
}


def algo_model(learner: str) -> type[Model]:
    """The model of the ``algo`` of ``learner`` (a learner of :data:`LEARNER_MODELS`)."""
    algo: type[Model] = LEARNER_MODELS[learner].model_fields["algo"].annotation  # type: ignore[assignment]
    return algo


_LearnerName = Annotated[str, OneOf(tuple(LEARNER_MODELS), "a learner")]


class LearnersFile(Model):
    """The layout of ``learners.json``; its entries are checked as learners (each under the
    file's ``common``) by :func:`agents.training.hyperparams_file.read_learners`."""

    model_config = ConfigDict(
        title="the learners' hyperparameters (agents/training/hyperparams/learners.json)",
        json_schema_extra={
            "description": "a JSON object with version, learners and optional common and comment"
        },
    )

    version: int = described("version of the table", "an integer ≥ 1", ge=1)
    comment: Annotated[str, described("what the table is for", "text")] | None = None
    common: dict[str, Any] = described(
        "settings every learner takes unless its entry gives them",
        "an object of settings every learner takes",
        default_factory=dict,
    )
    learners: dict[_LearnerName, dict[str, Any]] = described(
        "the learners' entries", "an object: learner → its hyperparameters"
    )


def learners_schema() -> dict[str, Any]:
    """The JSON Schema of ``learners.json``: ``common`` holds settings of
    :class:`~agents.training.hyperparameters.LearnerSettings` (none required), each learner's
    entry its model's fields, requiring those ``common`` cannot give."""
    file = model_schema(LearnersFile)
    classes: tuple[type[BaseModel], ...] = (LearnerSettings, *LEARNER_MODELS.values())
    models: list[tuple[type[BaseModel], Any]] = [(m, "validation") for m in classes]
    refs, schema = models_json_schema(models, schema_generator=SchemaGenerator)
    defs = schema["$defs"]
    base = set(LearnerSettings.model_fields)

    def entry(model: type[BaseModel], description: str) -> dict[str, Any]:
        name = refs[(model, "validation")]["$ref"].split("/")[-1]
        defs[name]["required"] = [k for k in defs[name].get("required", []) if k not in base]
        defs[name]["description"] = description
        return {"$ref": f"#/$defs/{name}"}

    props = file["properties"]
    props["common"] = {
        "title": props["common"]["title"],
        **entry(LearnerSettings, props["common"]["description"]),
    }
    learners = {
        name: entry(model, f"an object of {name}'s hyperparameters (and common's)")
        for name, model in LEARNER_MODELS.items()
    }
    props["learners"] = {
        **{k: v for k, v in props["learners"].items() if k != "additionalProperties"},
        "properties": learners,
        "additionalProperties": False,
    }
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", **file, "$defs": defs}
