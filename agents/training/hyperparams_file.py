"""Read the hyperparameter files into their models (:mod:`agents.training.hyperparameters`), with
one-line errors naming the file and the field.

``ppo.json`` (or ``aeromag train --hyperparams``) is read by :func:`read_ppo`, ``learners.json``
by :func:`read_learners`: first the text (a regular file of at most :data:`MAX_BYTES`, UTF-8,
JSON whose numbers are finite, ``NaN``, ``Infinity`` and overflowing literals such as ``1e400``
being no JSON numbers though Python's parser reads them, and whose keys appear once per
object), then the models check everything else in one pass. Every problem is a one-line
:class:`~aeromag_env.errors.HyperparameterError`: the file, the field as a dotted path, and
what it allows, e.g. ``…/learners.json: learners.sac.algo.gamma must be a number in (0, 1], got
2``.

The search spaces (:mod:`agents.search.space`) are read by :func:`read_checked` against their
hand-written JSON Schemas.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from pydantic import ConfigDict, TypeAdapter, ValidationError

from aeromag_env.errors import HyperparameterError
from agents.training.hyperparameters import PPOFile, PPOHyperparams, checked, model_schema
from agents.training.learner_hyperparameters import (
    LEARNER_MODELS,
    LearnerHyperparams,
    LearnersFile,
)
from agents.training.model_errors import problem, shown

#: Largest hyperparameter file [bytes]; the shipped ones are 3 to 5 kB.
MAX_BYTES = 2**20


class _Problem(Exception):
    """What is wrong with the file (becomes the tail of the HyperparameterError)."""


class _NotFinite:
    """A number literal that is no finite float (``NaN``, ``Infinity``, ``1e400``)."""

    def __init__(self, text: str) -> None:
        self.text = text


def read_ppo(path: str | Path) -> PPOFile:
    """The PPO hyperparameter file ``path`` as a
    :class:`~agents.training.hyperparameters.PPOFile`, every entry checked.

    Raises
    ------
    HyperparameterError
        One line: ``PATH: field problem``.
    """
    path = Path(path)
    doc = read_json(path)
    model: PPOFile = _validated(PPOFile, doc, path, ())
    for entry in model.scenarios.values():
        entry._version = model.version
    return model


def read_hyperparams(path: str | Path) -> dict[str, Any]:
    """The document of the PPO hyperparameter file ``path`` as it is written (a dict),
    checked as :func:`read_ppo` checks it."""
    path = Path(path)
    doc = read_json(path)
    _validated(PPOFile, doc, path, ())
    return dict(doc)


def read_learners(path: str | Path) -> dict[str, LearnerHyperparams]:
    """The learners of ``learners.json`` at ``path``: learner → its hyperparameters (the
    entry under the file's ``common``, a model of
    :data:`~agents.training.learner_hyperparameters.LEARNER_MODELS`), every learner checked.

    Raises
    ------
    HyperparameterError
        One line: ``PATH: learners.sac.algo.gamma must be …, got …`` (or ``common.…`` when
        the value came from ``common``).
    """
    path = Path(path)
    doc = read_json(path)
    table = _validated(LearnersFile, doc, path, ())
    learners: dict[str, LearnerHyperparams] = {}
    for name, entry in table.learners.items():
        merged = {**table.common, **entry}
        where: tuple[str, ...] = ("learners", name)
        try:
            learners[name] = LEARNER_MODELS[name].model_validate(merged)
        except ValidationError as e:
            key = e.errors()[0]["loc"][:1]
            if key and key[0] not in entry and key[0] in table.common:
                where = ("common",)
            schema = model_schema(LEARNER_MODELS[name])
            raise HyperparameterError(f"{path}: {problem(e, merged, schema, where)}") from None
        learners[name]._version = table.version
    return learners


def read_json(path: Path, head: str | None = None) -> Any:
    """The JSON document of ``path``: a regular file of at most :data:`MAX_BYTES`, UTF-8, its
    numbers finite, its keys once per object.

    Raises
    ------
    HyperparameterError
        One line: ``HEAD: problem`` (``HEAD``: the path, unless given).
    """
    head = head or str(path)
    try:
        return _parse(_text(path))
    except RecursionError:  # from the parser or the finiteness walk
        raise HyperparameterError(f"{head}: nested too deeply") from None
    except _Problem as e:
        raise HyperparameterError(f"{head}: {e}") from None


def _validated(model: type[Any], doc: Any, path: Path, prefix: tuple[str, ...]) -> Any:
    try:
        return model.model_validate(doc)
    except RecursionError:
        raise HyperparameterError(f"{path}: nested too deeply") from None
    except ValidationError as e:
        raise HyperparameterError(
            f"{path}: {problem(e, doc, model_schema(model), prefix)}"
        ) from None


def field_problem(model: type[Any], key: str, value: Any) -> str | None:
    """What is wrong with ``value`` as the field ``key`` of ``model`` (a model of
    :mod:`agents.training.hyperparameters`), e.g. ``must be a number in (0, 1], got 1.5``,
    or None. The field is checked alone, as the model checks it."""
    if value is None:
        return "must be a value, got null"
    config = ConfigDict(strict=True, allow_inf_nan=False, regex_engine="python-re")
    adapter = TypeAdapter(model.model_fields[key].rebuild_annotation(), config=config)
    try:
        adapter.validate_python(value)
    except ValidationError as e:
        return problem(e, {key: value}, model_schema(model), at=(key,)).removeprefix(key).strip()
    return None


def read_checked(path: str | Path, schema: Path, what: str) -> Any:
    """The JSON document of ``path``, checked against the JSON Schema file ``schema``: finite
    numbers, each key once per object, the schema's types and ranges.

    Raises
    ------
    HyperparameterError
        One line: ``bad WHAT in PATH: field: problem``.
    """
    path = Path(path)
    head = f"bad {what} in {path}"
    doc = read_json(path, head)
    try:
        _check_schema(doc, _validator(json.loads(schema.read_text(encoding="utf-8"))))
    except RecursionError:
        raise HyperparameterError(f"{head}: nested too deeply") from None
    except _Problem as e:
        raise HyperparameterError(f"{head}: {e}") from None
    return doc


def _text(path: Path) -> str:
    if path.exists() and not path.is_file() and not path.is_dir():  # a device or a pipe
        raise _Problem("not a regular file")
    try:
        size = path.stat().st_size
        if size > MAX_BYTES:
            raise _Problem(f"the file is larger than {MAX_BYTES} bytes ({size})")
        text = path.read_bytes().decode("utf-8-sig")
    except OSError as e:
        raise _Problem(str(e.strerror or e).lower()) from None
    except UnicodeDecodeError as e:
        raise _Problem(f"not UTF-8 text ({e.reason} at byte {e.start})") from None
    if not text.strip():
        raise _Problem("the file is empty")
    return text


def _parse(text: str) -> Any:
    try:
        doc = json.loads(
            text,
            parse_constant=_NotFinite,
            parse_float=_float,
            object_pairs_hook=_object,
        )
    except ValueError as e:  # JSONDecodeError, or an integer of more than 4300 digits
        raise _Problem(f"not valid JSON: {e}") from None
    for where, value in _leaves(doc, ()):
        if isinstance(value, _NotFinite):
            raise _Problem(f"{_dotted(where)} must be a finite number, got {value.text}")
    return doc


def _float(text: str) -> float | _NotFinite:
    value = float(text)
    return value if math.isfinite(value) else _NotFinite(text)


def _object(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise _Problem(f"key {key!r} appears twice in one object")
        out[key] = value
    return out


def _leaves(value: Any, where: tuple) -> Iterator[tuple[tuple, Any]]:
    yield where, value
    items = (
        value.items()
        if isinstance(value, dict)
        else enumerate(value)
        if isinstance(value, list)
        else ()
    )
    for key, item in items:
        yield from _leaves(item, (*where, key))


def _dotted(where: Any) -> str:
    return ".".join(str(p) for p in where) or "the document"


def _validator(schema: dict[str, Any]) -> Any:
    """A Draft 2020-12 validator of ``schema`` whose ``integer`` is a JSON integer only
    (the draft's own accepts 8.0, which stable-baselines3 cannot size a buffer with)."""
    try:
        import jsonschema
    except ImportError as e:  # the rl extra
        raise _Problem(
            f"validating needs jsonschema (pip install 'aeromag-env[rl]'): {e}"
        ) from None
    base = jsonschema.Draft202012Validator
    checker = base.TYPE_CHECKER.redefine(
        "integer", lambda _, v: isinstance(v, int) and not isinstance(v, bool)
    )
    validator = jsonschema.validators.extend(base, type_checker=checker)
    return validator(schema)


def _check_schema(doc: Any, validator: Any) -> None:
    import jsonschema

    error = jsonschema.exceptions.best_match(validator.iter_errors(doc))
    if error is None:
        return
    where = _dotted(error.absolute_path)
    if error.validator in ("required", "additionalProperties"):
        valid = ", ".join(error.schema.get("properties", {}))
        raise _Problem(f"{where}: {error.message}" + (f"; valid: {valid}" if valid else ""))
    described = error  # a branch of anyOf has no description of its own: its parent's
    while "description" not in described.schema and described.parent is not None:
        described = described.parent
    allowed = described.schema.get("description", error.message)
    raise _Problem(f"{where}: must be {allowed}, got {shown(error.instance)}")


def stored_hyperparams(summary: Mapping[str, Any]) -> PPOHyperparams | LearnerHyperparams:
    """The hyperparameters a training run stored (the ``hyperparams`` of its ``training.json``,
    or of a run of ``runs.json``), as the model of its learner (``summary["learner"]``, PPO when
    absent): files of every version read, their environment settings in today's terms.

    Raises
    ------
    ConfigError
        One line naming the field.
    """
    values = dict(summary["hyperparams"])
    version = values.pop("version", None)
    learner = summary.get("learner", "ppo")
    if learner == "ppo":
        return PPOHyperparams.from_entry(values, version or 0)
    hp = checked(LEARNER_MODELS[learner], values)
    hp._version = version
    return hp
