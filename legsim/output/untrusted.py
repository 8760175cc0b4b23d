"""Text that came from outside legsim: JSON documents read with bounded nesting, and strings
shown on a terminal with their control characters escaped.

A scene, a saved execution or a recording may come from someone else. Python's JSON parser
recurses once per nesting level (a document 100,000 levels deep raises RecursionError) and
accepts ``NaN`` and ``Infinity``, which strict JSON has not; a string holding ``ESC [ 2 J``
clears the terminal it is printed on. These helpers refuse the first and defuse the second.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping
from typing import Any

#: Deepest nesting of arrays and objects ``load_json`` accepts: legsim's own documents nest
#: four levels (meta -> summary -> outputs -> path); the margin is for a user's settings.
MAX_JSON_DEPTH = 64

_STRING = re.compile(r'"[^"\\]*(?:\\.[^"\\]*)*"', re.DOTALL)
_BRACKET = re.compile(r"[\[\]{}]")
# C0 controls but tab and newline, DEL, C1 controls, and the bidirectional overrides that
# reorder what a terminal shows.
_CONTROL = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u202a-\u202e\u2066-\u2069]")
_CONTROL_OR_NEWLINE = re.compile("[\x00-\x1f\x7f-\x9f\u202a-\u202e\u2066-\u2069]")


def json_depth(text: str, limit: int = MAX_JSON_DEPTH) -> int:
    """The nesting depth of the JSON document ``text`` (0 for a scalar), counting only up to
    ``limit + 1``: brackets inside strings are skipped without parsing the document."""
    depth = deepest = 0
    for match in _BRACKET.finditer(_STRING.sub('""', text)):
        depth += 1 if match.group() in "[{" else -1
        deepest = max(deepest, depth)
        if deepest > limit:
            break
    return deepest


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"{text} is beyond the range of a float")
    return value


def load_json(text: str, max_depth: int = MAX_JSON_DEPTH) -> Any:
    """Parse strict JSON: ValueError (with the reason) for a syntax error, ``NaN``,
    ``Infinity`` or a number beyond float range (``1e400``), or nesting deeper than
    ``max_depth``; never RecursionError."""
    if not isinstance(text, str):
        raise ValueError(f"expected JSON text, got {type(text).__name__}")
    if json_depth(text, max_depth) > max_depth:
        raise ValueError(f"nested more than {max_depth} levels deep")
    try:
        return json.loads(text, parse_constant=_no_constant, parse_float=_finite_float)
    except RecursionError:  # only reachable with a lowered interpreter recursion limit
        raise ValueError("nested too deep to parse") from None


def printable(text: Any, *, newlines: bool = True) -> str:
    """``str(text)`` with control characters (ANSI escapes, carriage returns, bidirectional
    overrides) written as ``\\x1b``-style escapes, so that printing it cannot move the cursor,
    recolour or clear the terminal. ``newlines=False`` escapes line breaks and tabs too (one-line
    fields such as a listing's columns)."""
    pattern = _CONTROL if newlines else _CONTROL_OR_NEWLINE
    return pattern.sub(lambda m: m.group().encode("unicode_escape").decode("ascii"), str(text))


def describe_type(value: Any) -> str:
    """A JSON value's type as a message names it."""
    return {
        bool: "a boolean",
        int: "an integer",
        float: "a number",
        str: "a string",
        list: "an array",
        dict: "an object",
        type(None): "null",
    }.get(type(value), type(value).__name__)


def check_object(
    doc: Any,
    schema: Mapping[str, tuple[type, ...]],
    where: str,
    *,
    optional: Mapping[str, tuple[type, ...]] | None = None,
) -> dict[str, Any]:
    """``doc`` as a dict whose keys in ``schema`` are present and whose keys in ``schema`` or
    ``optional`` have one of the given types (``bool`` is never taken for a number); ValueError
    naming ``where`` and the key otherwise."""
    if not isinstance(doc, dict):
        raise ValueError(f"{where} is {describe_type(doc)}, expected an object")
    missing = [key for key in schema if key not in doc]
    if missing:
        raise ValueError(f"{where} lacks {missing}")
    for key, types in {**(optional or {}), **schema}.items():
        if key in doc and not _has_type(doc[key], types):
            names = " or ".join(t.__name__ if t is not type(None) else "null" for t in types)
            raise ValueError(f"{where}.{key} is {describe_type(doc[key])}, expected {names}")
    return doc


def _has_type(value: Any, types: tuple[type, ...]) -> bool:
    if isinstance(value, bool):
        return bool in types
    if isinstance(value, float):
        # JSON reads 1e400 as inf without complaint: a number must be finite.
        return float in types and math.isfinite(value)
    if isinstance(value, int) and int in types:
        # JSON integers are unbounded: 10**400 would overflow every float format.
        return abs(value) < 2**63
    return isinstance(value, types)


def check_list(value: Any, types: tuple[type, ...], where: str) -> list[Any]:
    """``value`` as a list whose items have one of ``types``; ValueError naming ``where``."""
    if not isinstance(value, list):
        raise ValueError(f"{where} is {describe_type(value)}, expected an array")
    for k, item in enumerate(value):
        if not _has_type(item, types):
            raise ValueError(
                f"{where}[{k}] is {describe_type(item)}, expected " + " or ".join(t.__name__ for t in types)
            )
    return value
