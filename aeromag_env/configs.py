"""What every configuration dataclass shares: validation helpers and the JSON round trip.

Configurations are frozen keyword-only dataclasses that validate themselves in
``__post_init__`` (:func:`check`, :func:`require_positive`, :func:`require_nonnegative`) with a
message naming the field and its unit, and pass through JSON (:func:`to_json` /
:func:`from_json`), since a configuration given to ``gym.make`` or written into a flight file may
come back as a dict.
"""

from __future__ import annotations

import dataclasses
import json
import math
import types
import typing
from typing import Any, TypeVar, Union

from aeromag_env.errors import ConfigError


def check(ok: bool, message: str) -> None:
    """A :class:`ConfigError` with ``message`` unless ``ok``."""
    if not ok:
        raise ConfigError(message)


def require_positive(obj: object, *names: str) -> None:
    """Each attribute ``names`` of ``obj`` finite and > 0."""
    for nm in names:
        v = getattr(obj, nm)
        check(math.isfinite(v) and v > 0, f"{type(obj).__name__}.{nm} must be > 0, got {v}")


def require_nonnegative(obj: object, *names: str) -> None:
    """Each attribute ``names`` of ``obj`` finite and ≥ 0."""
    for nm in names:
        v = getattr(obj, nm)
        check(math.isfinite(v) and v >= 0, f"{type(obj).__name__}.{nm} must be ≥ 0, got {v}")


def to_dict(cfg: Any) -> dict[str, Any]:
    """Dataclass → plain dict (JSON-serialisable)."""
    return dataclasses.asdict(cfg)


def to_json(cfg: Any) -> str:
    """Dataclass → JSON string (sorted keys, so equal configs give equal text)."""
    return json.dumps(to_dict(cfg), sort_keys=True)


T = TypeVar("T")


def from_dict(cls: type[T], data: dict[str, Any] | Any) -> T:
    """Plain dict → dataclass ``cls`` (recursively); unknown keys give a one-line error.

    An instance of ``cls`` is returned unchanged, so callers may pass either form. A class
    with a ``canonical_dict(data) -> dict`` static method reads its own dicts first (e.g.
    :class:`~aeromag_env.environment.config.EnvConfig`: a preset name and partial specs).
    """
    if isinstance(data, cls):
        return data
    if not isinstance(data, dict):
        raise ConfigError(f"{cls.__name__} expects a mapping, got {type(data).__name__}")
    canonical = getattr(cls, "canonical_dict", None)
    if canonical is not None:
        data = canonical(data)
    hints = _type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]
    unknown = sorted(set(data) - set(names))
    if unknown:
        raise ConfigError(
            f"{cls.__name__}: unknown field(s) {', '.join(unknown)}; valid: {', '.join(names)}"
        )
    kwargs = {k: _convert(hints[k], v, f"{cls.__name__}.{k}") for k, v in data.items()}
    try:
        return cls(**kwargs)
    except TypeError as e:
        raise ConfigError(f"{cls.__name__}: {e}") from None


_hints: dict[type, dict[str, Any]] = {}


def _type_hints(cls: type) -> dict[str, Any]:
    """``typing.get_type_hints`` once per class (it compiles the string annotations)."""
    if cls not in _hints:
        _hints[cls] = typing.get_type_hints(cls)
    return _hints[cls]


def from_json(cls: type[T], text: str) -> T:
    """JSON string → dataclass ``cls``."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as e:
        raise ConfigError(f"configuration is not valid JSON: {e}") from None
    return from_dict(cls, data)


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{where} expects numbers, got {value!r}")
    return float(value)


def _convert(tp: Any, value: Any, where: str) -> Any:
    origin = typing.get_origin(tp)
    if origin in (Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        return None if value is None else _convert(args[0], value, where)
    if dataclasses.is_dataclass(tp):
        return from_dict(tp, value)  # type: ignore[arg-type]
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"{where} expects a list, got {value!r}")
        item = typing.get_args(tp)[0]
        if dataclasses.is_dataclass(item):
            return tuple(from_dict(item, v) for v in value)  # type: ignore[arg-type]
        if item is str:
            if not all(isinstance(v, str) for v in value):
                raise ConfigError(f"{where} expects a list of names, got {value!r}")
            return tuple(value)
        return tuple(_number(v, where) for v in value)
    if origin is dict:
        if not isinstance(value, dict):
            raise ConfigError(f"{where} expects a mapping, got {value!r}")
        return dict(value)
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{where} expects a number, got {value!r}")
        return float(value)
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{where} expects an integer, got {value!r}")
        return value
    if tp is bool and not isinstance(value, bool):
        raise ConfigError(f"{where} expects true or false, got {value!r}")
    if tp is str and not isinstance(value, str):
        raise ConfigError(f"{where} expects a string, got {value!r}")
    return value
