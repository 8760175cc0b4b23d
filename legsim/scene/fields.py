"""Error helpers shared by the scene's core sections and its tool sections: every message
starts with the file and names the field as a dotted path."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from ..errors import SceneError


def field_error(path: Path, where: str, message: str) -> SceneError:
    """The error for field ``where`` (a dotted path) of scene ``path``."""
    return SceneError(f"{path}: {where}: {message}")


def table_at(path: Path, data: Mapping[str, Any], key: str, where: str | None = None) -> dict[str, Any]:
    """``data[key]`` as a table ({} when absent); a SceneError naming ``where`` when it is not one."""
    value = data.get(key, {})
    if not isinstance(value, dict):
        raise field_error(path, where or key, f"expected a table, got {describe(value)}")
    return value


def describe(value: Any) -> str:
    """A TOML value as a message shows it: its TOML type, then its repr."""
    kind = {bool: "boolean", int: "integer", float: "float", str: "string", list: "array", dict: "table"}.get(
        type(value), type(value).__name__
    )
    return f"{kind} {value!r}"


def check_keys(path: Path, table: Mapping[str, Any], allowed: Iterable[str], where: str) -> None:
    """Refuse keys of ``table`` that are not in ``allowed``, listing the allowed ones."""
    allowed = list(allowed)
    unknown = sorted(set(table) - set(allowed))
    if unknown:
        raise field_error(path, where, f"unknown key(s) {unknown}; allowed: {allowed}")
