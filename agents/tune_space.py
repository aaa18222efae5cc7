"""Read the search space of ``aeromag tune`` (``agents/hyperparams/tune_space.json`` or
``--space``) and turn it into Ray Tune's.

The file maps hyperparameters of the PPO hyperparameter file (:mod:`agents.hyperparams_file`)
to distributions::

    {"version": 1,
     "space": {"learning_rate": {"distribution": "loguniform", "low": 3e-5, "high": 1e-3},
               "n_steps": {"distribution": "choice", "values": [128, 256, 512]}}}

``uniform`` and ``loguniform`` draw numbers in ``[low, high]`` (for number hyperparameters),
``randint`` integers in ``[low, high]`` (both included), ``choice`` one of ``values`` (any
hyperparameter, e.g. ``net_arch`` or ``normalize_reward``). The JSON Schema
(``tune_space.schema.json``) checks the keys and the layout; this module checks what it
cannot say: which fields each distribution needs, ``low < high``, ``loguniform`` above 0, and
that every bound and value is one the hyperparameter file accepts for that key (its range in
``ppo.schema.json``), so no trial is sampled that training would refuse. Every problem is a
one-line :class:`~aeromag_env.errors.HyperparameterError` naming the file and the field.
Ray is imported by :func:`tune_domains` only.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from aeromag_env.errors import HyperparameterError
from agents.hyperparams_file import SCHEMA, read_checked, value_problem

SPACE = Path(__file__).with_name("hyperparams") / "tune_space.json"
SPACE_SCHEMA = SPACE.with_name("tune_space.schema.json")
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
    space = read_checked(path, SPACE_SCHEMA, "search space")["space"]
    kinds = _kinds()
    for key, dim in space.items():
        problem = _dimension_problem(key, dim, kinds[key])
        if problem is not None:
            raise HyperparameterError(f"bad search space in {path}: space.{key}: {problem}")
    return space


def _kinds() -> dict[str, str]:
    """Each hyperparameter's kind in the hyperparameter schema: integer, number or other."""
    props = json.loads(SCHEMA.read_text(encoding="utf-8"))["$defs"]["scenario"]["properties"]
    kinds = {}
    for key, prop in props.items():
        types = [prop.get("type")] + [branch.get("type") for branch in prop.get("anyOf", [])]
        kinds[key] = "integer" if "integer" in types else "number" if "number" in types else ""
    return kinds


def _dimension_problem(key: str, dim: dict[str, Any], kind: str) -> str | None:
    """What is wrong with the distribution ``dim`` of ``key`` (of ``kind``), or None."""
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
