"""A pydantic error on a hyperparameter document as one line: the field as a dotted path and
what it allows.

The models of :mod:`agents.training.hyperparameters` declare what each field allows as its
``description``; :func:`problem` follows an error's location through the document and through
the model's JSON Schema, and says ``scenarios.suite.gamma must be a number in (0, 1], got 2``
(or ``... is missing (required)``, ``... is unknown; valid: ...``, ``... is no valid name``).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any


def problem(
    error: Any,
    doc: Any,
    schema: Mapping[str, Any],
    prefix: tuple[str, ...] = (),
    at: tuple[str, ...] = (),
) -> str:
    """The first error of the pydantic ``ValidationError`` ``error`` on the document ``doc`` as
    one line: the field as a dotted path (``prefix`` first) and what it allows (the
    ``description`` of the field in the JSON Schema ``schema`` of the model), e.g.
    ``scenarios.suite.gamma must be a number in (0, 1], got 2``; ``at``: where in ``doc`` the
    value validated was (its error's location is relative to it)."""
    first = error.errors(include_url=False)[0]
    loc, kind = (*at, *first["loc"]), first["type"]
    path, nodes, value, found = _walk(doc, schema, loc)
    where = ".".join(str(p) for p in (*prefix, *path)) or "the document"
    if kind == "missing":
        return f"{where} is missing (required)"
    if kind == "extra_forbidden":
        valid = ", ".join(_resolved(schema, nodes[-2]).get("properties", {}))
        return f"{where} is unknown; valid: {valid}"
    if "[key]" in loc:
        names = _resolved(schema, nodes[-2]).get("propertyNames", {})
        return f"{where} is no valid name: must be {names.get('description', 'another name')}"
    if kind == "value_error":
        return f"{where}: {first['msg'].removeprefix('Value error, ')}"
    allowed = next(
        (d for node in reversed(nodes) if (d := _resolved(schema, node).get("description"))),
        first["msg"],
    )
    return f"{where} must be {allowed}, got {shown(value if found else first['input'])}"


def _walk(doc: Any, schema: Mapping[str, Any], loc: tuple) -> tuple[list, list, Any, bool]:
    """Follow ``loc`` (a pydantic error location) in ``doc`` and in ``schema``: the keys found
    (the last one too when it is missing from ``doc``), the schema node of each (the root
    first), the value reached and whether the whole of ``loc`` was followed."""
    path: list = []
    nodes: list = [schema]
    value = doc
    for i, part in enumerate(loc):
        if _has(value, part):
            value = value[part]
        elif isinstance(value, Mapping) and i == len(loc) - 1 and part != "[key]":
            path.append(part)  # a missing key
            nodes.append(_child(schema, nodes[-1], part))
            return path, nodes, None, False
        else:  # a branch of a union, or a mapping's key
            return path, nodes, value, "[key]" in loc[i:]
        path.append(part)
        nodes.append(_child(schema, nodes[-1], part))
    return path, nodes, value, True


def _has(value: Any, part: Any) -> bool:
    """Whether ``value`` (a JSON object or list) has the key or index ``part``."""
    if isinstance(value, Mapping):
        return isinstance(part, str) and part in value
    return isinstance(value, list | tuple) and isinstance(part, int) and 0 <= part < len(value)


def _resolved(root: Mapping[str, Any], node: Mapping[str, Any]) -> dict[str, Any]:
    """``node`` with its ``$ref`` resolved in ``root``'s ``$defs`` (the node's own keys win)."""
    node = dict(node)
    ref = node.pop("$ref", None)
    if ref is None:
        return node
    return {**_resolved(root, root["$defs"][ref.split("/")[-1]]), **node}


def _child(root: Mapping[str, Any], node: Mapping[str, Any], part: Any) -> dict[str, Any]:
    """The schema of ``part`` (a key or an index) of a value of schema ``node``."""
    node = _resolved(root, node)
    if isinstance(part, str) and part in node.get("properties", {}):
        return dict(node["properties"][part])
    if isinstance(part, int) and isinstance(node.get("items"), dict):
        return dict(node["items"])
    if isinstance(node.get("additionalProperties"), dict):
        return dict(node["additionalProperties"])
    return {}


def shown(value: Any) -> str:
    """``value`` as a message shows it: JSON text of at most 40 characters, or its kind."""
    if isinstance(value, Mapping):
        return "an object"
    if isinstance(value, list | tuple):
        return "a list"
    try:
        text = json.dumps(value, ensure_ascii=False)
    except (TypeError, ValueError):
        text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."
