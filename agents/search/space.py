"""Read the search space of ``aeromag tune`` (``agents/search/spaces/tune_space.json`` or
``--space``) and turn it into Ray Tune's.

The file maps hyperparameters of the PPO hyperparameter file (the fields of
:class:`agents.training.hyperparameters.PPOHyperparams`) to distributions::

    {"version": 1,
     "space": {"learning_rate": {"distribution": "loguniform", "low": 3e-5, "high": 1e-3},
               "n_steps": {"distribution": "choice", "values": [128, 256, 512]}}}

``uniform`` and ``loguniform`` draw numbers in ``[low, high]`` (for number hyperparameters),
``randint`` integers in ``[low, high]`` (both included), ``choice`` one of ``values`` (any
hyperparameter, e.g. ``net_arch`` or ``normalize_reward``). The JSON Schema
(``tune_space.schema.json``) checks the keys and the layout; this module checks what it
cannot say: which fields each distribution needs, ``low < high``, ``loguniform`` above 0, and
that every bound and value is one the hyperparameter file accepts for that key (the field's
type and range in the model), so no trial is sampled that training would refuse. Every
problem is a one-line :class:`~aeromag_env.errors.HyperparameterError` naming the file and the
field.

The learners' file (``agents/search/spaces/tune_space_learners.json``, :func:`read_learner_space`)
holds one such space per learner of ``aeromag tune --learner`` under ``learners``, its keys
fields of the learner's ``algo`` (constructor parameters of its algorithm:
:class:`~agents.training.hyperparameters.SACAlgo`… in
``agents/training/hyperparams/learners.json``), checked the same way against those fields.
Ray is imported by :func:`tune_domains` only.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from aeromag_env.errors import HyperparameterError
from agents.training.hyperparams_file import field_problem, read_checked

SPACE = Path(__file__).with_name("spaces") / "tune_space.json"
SPACE_SCHEMA = SPACE.with_name("tune_space.schema.json")
#: The learners' search spaces (``aeromag tune --learner``) and their schema.
LEARNER_SPACES = SPACE.with_name("tune_space_learners.json")
LEARNER_SPACES_SCHEMA = SPACE.with_name("tune_space_learners.schema.json")
#: The fields of each distribution (besides ``distribution``).
FIELDS = {
    "uniform": ("low", "high"),
    "loguniform": ("low", "high"),
    "randint": ("low", "high"),
    "choice": ("values",),
}


def read_space(path: str | Path = SPACE) -> dict[str, dict[str, Any]]:
    """The search space of the file ``path``: hyperparameter → its distribution, validated.

    Returns
    -------
    dict
        ``{key: {"distribution": name, "low": L, "high": H}}`` or ``{…, "values": [...]}``.

    Raises
    ------
    HyperparameterError
        One line: ``bad search space in PATH: space.KEY: problem``.
    """
    from agents.training.hyperparameters import PPOHyperparams

    space = read_checked(path, SPACE_SCHEMA, "search space")["space"]
    for key, dim in space.items():
        problem = dimension_problem(key, dim, *_field(PPOHyperparams, key))
        if problem is not None:
            raise HyperparameterError(f"bad search space in {path}: space.{key}: {problem}")
    return space


def _field(model: type[Any], key: str) -> tuple[str, Callable[[str, Any], str | None]]:
    """The kind of the field ``key`` of ``model`` (integer, number or other: what its JSON
    Schema says) and the check of a value of it."""
    from agents.training.hyperparameters import model_schema

    prop = model_schema(model)["properties"][key]
    types = [prop.get("type")] + [branch.get("type") for branch in prop.get("anyOf", [])]
    kind = "integer" if "integer" in types else "number" if "number" in types else ""
    return kind, lambda name, value: field_problem(model, name, value)


def read_learner_space(learner: str, path: str | Path = LEARNER_SPACES) -> dict[str, Any]:
    """The search space of ``learner`` in the learners' file ``path``, validated (every
    learner's space in it, so that a bad file is refused whichever learner is asked for).

    Returns
    -------
    dict
        ``{key: distribution}`` as :func:`read_space`'s, each key a field of the learner's
        ``algo`` (a constructor keyword of its algorithm).

    Raises
    ------
    HyperparameterError
        One line: ``bad search space in PATH: learners.LEARNER.KEY: problem``.
    """
    from agents.training.learner_hyperparameters import algo_model

    spaces = read_checked(path, LEARNER_SPACES_SCHEMA, "search space")["learners"]
    for name, space in spaces.items():
        algo = algo_model(name)
        for key, dim in space.items():
            where = f"bad search space in {path}: learners.{name}.{key}"
            if key not in algo.model_fields:
                raise HyperparameterError(
                    f"{where}: not a hyperparameter of {name}'s algo; valid: "
                    f"{', '.join(algo.model_fields)}"
                )
            problem = dimension_problem(key, dim, *_field(algo, key))
            if problem is not None:
                raise HyperparameterError(f"{where}: {problem}")
    if learner not in spaces:
        raise HyperparameterError(
            f"bad search space in {path}: learners: no space for {learner}; it has "
            f"{', '.join(spaces)}"
        )
    return dict(spaces[learner])


def dimension_problem(
    key: str, dim: dict[str, Any], kind: str, value_problem: Callable[[str, Any], str | None]
) -> str | None:
    """What is wrong with the distribution ``dim`` of ``key`` (of ``kind``: integer, number or
    other), its bounds or values checked by ``value_problem(key, value)``; or None."""
    name = dim["distribution"]
    given = set(dim) - {"distribution"}
    if given != set(FIELDS[name]):
        got = ", ".join(sorted(given)) or "none"
        return f"{name} takes {' and '.join(FIELDS[name])}, got {got}"
    if name == "choice":
        values = dim["values"]
    else:
        if name == "randint" and kind != "integer":
            return f"randint draws integers; {key} is not one (use uniform, loguniform or choice)"
        if name != "randint" and kind != "number":
            return f"{name} draws real numbers; {key} is not one (use randint or choice)"
        values = [dim["low"], dim["high"]]
        if not dim["low"] < dim["high"]:
            return f"needs low < high, got low {dim['low']} and high {dim['high']}"
        if name == "loguniform" and not dim["low"] > 0:
            return f"loguniform needs low > 0, got {dim['low']}"
    for value in values:
        problem = value_problem(key, value)
        if problem is not None:
            return f"{json.dumps(value)} is no valid {key}: {problem}"
    return None


def tune_domains(space: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """Ray Tune's search space for ``space`` (of :func:`read_space`)."""
    from ray import tune

    domains = {}
    for key, dim in space.items():
        name = dim["distribution"]
        if name == "choice":
            domains[key] = tune.choice(dim["values"])
        elif name == "randint":  # Tune's upper bound is excluded
            domains[key] = tune.randint(int(dim["low"]), int(dim["high"]) + 1)
        elif name == "loguniform":
            domains[key] = tune.loguniform(dim["low"], dim["high"])
        else:
            domains[key] = tune.uniform(dim["low"], dim["high"])
    return domains


def plain(config: dict[str, Any]) -> dict[str, Any]:
    """``config`` with numpy scalars (Tune draws them) as Python numbers, for JSON."""
    return {k: v.item() if hasattr(v, "item") else v for k, v in config.items()}


def recorded_path(path: str | Path) -> str:
    """``path`` as a search's record names it: relative to the working directory when it lies
    under it (a checkout's own files by their repository path, so that a committed record does
    not carry the machine it ran on), else as given."""
    p = Path(path)
    try:
        return p.resolve().relative_to(Path.cwd().resolve()).as_posix()
    except ValueError:
        return str(path)
