"""One clear error for bad user input, and the helpers that read YAFS JSON inputs.

Every loader in the core accepts either an already-parsed JSON value (YAFS's own signatures
take dicts/lists) or a path to a JSON file; with a path, errors name the file.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from typing import Any, Literal, overload


class YAFSInputError(ValueError):
    """A topology/application/placement/population input is malformed.

    The message is one line: ``<source>: <entry>: field '<field>': <problem>``.

    Attributes:
        source: the file name, or a description such as ``"topology (dict)"``.
        entry: which entry is wrong (e.g. ``"link[3]"``), or ``""`` for the whole document.
        field: the offending key, or ``""``.
        problem: what is wrong.
    """

    def __init__(self, source: str, entry: str, field: str, problem: str) -> None:
        self.source = source
        self.entry = entry
        self.field = field
        self.problem = problem
        parts = [source]
        if entry:
            parts.append(entry)
        if field:
            parts.append(f"field '{field}'")
        parts.append(problem)
        super().__init__(": ".join(parts))


def read_json_input(data: Any, kind: str) -> tuple[Any, str]:
    """Return ``(parsed_json, source_name)`` for a dict/list or a path to a JSON file.

    Args:
        data: a parsed JSON value, or a ``str``/``os.PathLike`` path to a JSON file.
        kind: what the input is (``"topology"``, ``"application"``...), used to name
            in-memory sources.

    Raises:
        YAFSInputError: the file cannot be read or is not JSON.
    """
    if isinstance(data, (str, os.PathLike)):
        source = os.fspath(data)
        try:
            with open(source, encoding="utf-8") as handle:
                text = handle.read()
        except OSError as exc:
            raise YAFSInputError(source, "", "", f"cannot read {kind} file ({exc.strerror})") from None
        try:
            return json.loads(text), source
        except json.JSONDecodeError as exc:
            raise YAFSInputError(
                source, "", "", f"not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})"
            ) from None
    return data, f"{kind} (in-memory)"


def require_mapping(value: Any, source: str, entry: str) -> Mapping[str, Any]:
    """Check that ``value`` is a JSON object."""
    if not isinstance(value, Mapping):
        raise YAFSInputError(source, entry, "", f"expected an object, got {type(value).__name__}")
    return value


def require_list(container: Mapping[str, Any], key: str, source: str, entry: str) -> list[Any]:
    """Return ``container[key]`` checked to be a JSON list."""
    if key not in container:
        raise YAFSInputError(source, entry, key, "missing required key")
    value = container[key]
    if not isinstance(value, list):
        raise YAFSInputError(source, entry, key, f"expected a list, got {type(value).__name__}")
    return value


def require_key(container: Mapping[str, Any], key: str, source: str, entry: str) -> Any:
    """Return ``container[key]`` or raise naming the missing key."""
    if key not in container:
        raise YAFSInputError(source, entry, key, "missing required key")
    return container[key]


def require_id(container: Mapping[str, Any], key: str, source: str, entry: str) -> Any:
    """Return a node/app identifier: a string or an integer (not a bool, list or float)."""
    value = require_key(container, key, source, entry)
    if isinstance(value, bool) or not isinstance(value, (int, str)):
        raise YAFSInputError(
            source, entry, key, f"expected an integer or string id, got {type(value).__name__}"
        )
    return value


@overload
def require_number(container: Mapping[str, Any], key: str, source: str, entry: str, *,
                   positive: bool = ..., required: Literal[True] = ...) -> float | int: ...


@overload
def require_number(container: Mapping[str, Any], key: str, source: str, entry: str, *,
                   positive: bool = ..., required: bool) -> float | int | None: ...


def require_number(
    container: Mapping[str, Any],
    key: str,
    source: str,
    entry: str,
    *,
    positive: bool = False,
    required: bool = True,
) -> float | int | None:
    """Return a finite, non-negative number (strictly positive if ``positive``).

    Returns ``None`` when the key is absent and not ``required``.
    """
    if key not in container:
        if required:
            raise YAFSInputError(source, entry, key, "missing required key")
        return None
    value = container[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise YAFSInputError(source, entry, key, f"expected a number, got {type(value).__name__}")
    if not math.isfinite(value):
        raise YAFSInputError(source, entry, key, f"must be finite, got {value}")
    if value < 0 or (positive and value == 0):
        bound = "positive" if positive else "non-negative"
        raise YAFSInputError(source, entry, key, f"must be {bound}, got {value}")
    return value
