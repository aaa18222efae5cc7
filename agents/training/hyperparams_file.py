"""Read a PPO hyperparameter file (``agents/training/hyperparams/ppo.json`` or ``--hyperparams``)
and validate it against its JSON Schema (``agents/training/hyperparams/ppo.schema.json``) before
training.

The schema holds every key, its type and its allowed range (``description``); ``jsonschema``
checks the document against it. Two things JSON Schema cannot say are checked here: numbers
must be finite (``NaN``, ``Infinity`` and overflowing literals such as ``1e400`` are not JSON
numbers, though Python's parser reads them) and a key may appear once per object; the
``env_kwargs`` go through :class:`~aeromag_env.environment.env.EnvConfig`'s own validation.
Every problem is a one-line :class:`~aeromag_env.errors.HyperparameterError` naming the file,
the field (a dotted path such as ``scenarios.nonstationary.gamma``) and what it allows.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from aeromag_env.configs import from_dict
from aeromag_env.environment.env import EnvConfig
from aeromag_env.errors import ConfigError, HyperparameterError

SCHEMA = Path(__file__).with_name("hyperparams") / "ppo.schema.json"
#: Largest hyperparameter file [bytes]; the shipped one is 3 kB.
MAX_BYTES = 2**20


class _Problem(Exception):
    """What is wrong with the file (becomes the tail of the HyperparameterError)."""


class _NotFinite:
    """A number literal that is no finite float (``NaN``, ``Infinity``, ``1e400``)."""

    def __init__(self, text: str) -> None:
        self.text = text


def read_hyperparams(path: str | Path) -> dict[str, Any]:
    """The document of the hyperparameter file ``path``, validated.

    Raises
    ------
    HyperparameterError
        One line: ``bad hyperparameters in PATH: field: problem``.
    """
    path = Path(path)
    doc = read_checked(path, SCHEMA, "hyperparameters")
    for name, hp in doc["scenarios"].items():
        try:
            from_dict(EnvConfig, hp["env_kwargs"])
        except ConfigError as e:
            raise HyperparameterError(
                f"bad hyperparameters in {path}: scenarios.{name}.env_kwargs: {e}"
            ) from None
    return doc


def read_checked(path: str | Path, schema: Path, what: str) -> Any:
    """The JSON document of ``path``, checked against the JSON Schema file ``schema``: finite
    numbers, each key once per object, the schema's types and ranges.

    Raises
    ------
    HyperparameterError
        One line: ``bad WHAT in PATH: field: problem``.
    """
    path = Path(path)
    try:
        doc = _parse(_text(path))
        _check_schema(doc, _validator(json.loads(schema.read_text(encoding="utf-8"))))
    except RecursionError:  # from the parser, the finiteness walk or the schema's
        raise HyperparameterError(f"bad {what} in {path}: nested too deeply") from None
    except _Problem as e:
        raise HyperparameterError(f"bad {what} in {path}: {e}") from None
    return doc


def schema_problem(value: Any, schema: dict[str, Any]) -> str | None:
    """What is wrong with the JSON value ``value`` under the JSON Schema ``schema`` (its
    ``description`` says what is allowed: ``must be a number in (0, 1], got 1.5``), or None."""
    try:
        _check_schema(value, _validator(schema))
    except _Problem as e:
        return str(e).removeprefix("the document: ")
    return None


def value_problem(key: str, value: Any) -> str | None:
    """What is wrong with ``value`` as the hyperparameter ``key`` of a scenario entry (its
    range in :data:`SCHEMA`, e.g. ``must be a number in (0, 1], got 1.5``), or None."""
    scenario = json.loads(SCHEMA.read_text(encoding="utf-8"))["$defs"]["scenario"]
    try:
        _check_schema(value, _validator(scenario["properties"][key]))
    except _Problem as e:
        return str(e).removeprefix("the document: ")
    return None


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
    for where, value in _walk(doc, ()):
        if isinstance(value, _NotFinite):
            raise _Problem(f"{_dotted(where)}: must be a finite number, got {value.text}")
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


def _walk(value: Any, where: tuple) -> Iterator[tuple[tuple, Any]]:
    yield where, value
    items = (
        value.items()
        if isinstance(value, dict)
        else enumerate(value)
        if isinstance(value, list)
        else ()
    )
    for key, item in items:
        yield from _walk(item, (*where, key))


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
    raise _Problem(f"{where}: must be {allowed}, got {_shown(error.instance)}")


def _shown(value: Any) -> str:
    if isinstance(value, dict):
        return "an object"
    if isinstance(value, list):
        return "a list"
    text = json.dumps(value, ensure_ascii=False)
    return text if len(text) <= 40 else text[:37] + "..."
