"""Finding and reading scene files: names looked up in ``LEGSIM_SCENE_PATH`` and the bundled
scenes, TOML parsing with the line of a syntax error, and ``key.path=value`` overrides."""

from __future__ import annotations

import os
import stat
import tomllib
from collections.abc import Iterable, Mapping
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import LegsimError, SceneError
from ..output.files import file_kind
from .fields import field_error

if TYPE_CHECKING:
    from ..builders import Param

SCENE_PATH_ENV = "LEGSIM_SCENE_PATH"

#: Largest scene file read (bytes): the bundled ones are below 3 kB.
MAX_SCENE_BYTES = 1 << 20
#: Deepest nesting of tables and arrays in a scene: the bundled ones nest four levels.
MAX_SCENE_DEPTH = 32


# -- finding scenes ----------------------------------------------------------------------------
def bundled_dir() -> Path:
    """The folder of the bundled scenes: the package data of ``legsim.scenarios`` (the
    repository's ``scenarios/`` folder in a checkout)."""
    return Path(str(resources.files("legsim.scenarios")))


def search_dirs() -> list[Path]:
    """Directories searched for scene names: ``LEGSIM_SCENE_PATH`` entries, then the bundled one."""
    dirs = [Path(p).expanduser() for p in os.environ.get(SCENE_PATH_ENV, "").split(os.pathsep) if p.strip()]
    dirs.append(bundled_dir())
    return dirs


def scene_files() -> dict[str, Path]:
    """Every scene a name can reach: name -> file, the first directory of ``search_dirs`` winning."""
    found: dict[str, Path] = {}
    for directory in search_dirs():
        if not directory.is_dir():
            continue
        for path in sorted(directory.glob("*.toml")):
            found.setdefault(path.stem, path)
    return found


def resolve_scene_path(path_or_name: str | os.PathLike[str]) -> Path:
    """The file of a scene given by path or by name; SceneError when there is none."""
    if isinstance(path_or_name, os.PathLike) or (isinstance(path_or_name, str) and path_or_name):
        candidate = Path(path_or_name)
    else:
        raise SceneError(f"a scene must be a path or a name, got {path_or_name!r}")
    if candidate.is_file():
        return candidate
    if candidate.exists():
        raise SceneError(f"{candidate}: not a scene file (it is {file_kind(candidate.stat().st_mode)})")
    text = str(path_or_name)
    looks_like_path = isinstance(path_or_name, os.PathLike) or os.sep in text or "/" in text or text.endswith(".toml")
    if not looks_like_path:
        for directory in search_dirs():
            path = directory / f"{text}.toml"
            if path.is_file():
                return path
        known = sorted(scene_files())
        raise SceneError(
            f"unknown scene '{text}': no such file, and no scene of that name in "
            f"{[str(d) for d in search_dirs()]}; known scenes: {known}"
        )
    hint = ""
    if candidate.suffix == ".toml" and candidate.parent == Path(".") and candidate.stem in scene_files():
        hint = f" (the scene named '{candidate.stem}' is {scene_files()[candidate.stem]}: run it by name)"
    raise SceneError(f"{candidate}: no such scene file{hint}")


# -- overrides ---------------------------------------------------------------------------------
def parse_override(text: str) -> tuple[list[str], Any]:
    """Split ``key.path=value`` into the key path and the value, read as a TOML literal
    (``1e-4``, ``true``, ``"x"``, ``{ a = 1 }``, ``[1, 2]``) or else as a bare string."""
    if not isinstance(text, str) or "=" not in text:
        raise SceneError(f"--set {text!r}: expected key.path=value, e.g. integrator.h=1e-4")
    key, raw = text.split("=", 1)
    parts = [p.strip() for p in key.strip().split(".")]
    if not key.strip() or any(not p for p in parts):
        raise SceneError(f"--set {text!r}: the key must be a dotted path of names, e.g. integrator.h=1e-4")
    raw = raw.strip()
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    except RecursionError:
        raise SceneError(f"--set {key.strip()}: the value is nested more than {MAX_SCENE_DEPTH} levels deep") from None
    return parts, value


def apply_overrides(data: dict[str, Any], overrides: Iterable[str]) -> list[str]:
    """Apply ``key.path=value`` overrides to the scene's TOML tables in place (tables along the
    path are created as needed; an effect set to ``true`` becomes a table of parameters)."""
    applied = []
    for text in overrides:
        parts, value = parse_override(text)
        node = data
        for depth, part in enumerate(parts[:-1]):
            child = node.get(part)
            where = ".".join(parts[: depth + 1])
            if child is None or child is True:
                child = node[part] = {}
            elif child is False:
                raise SceneError(
                    f"--set {text}: {where} is false (switched off); switch it on with "
                    f"--set {where}=true before setting its fields"
                )
            elif not isinstance(child, dict):
                raise SceneError(
                    f"--set {text}: {where} is {child!r}, not a table, so it has no field '{parts[depth + 1]}'"
                )
            node = child
        node[parts[-1]] = value
        applied.append(text)
    return applied


def read_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML scene file; SceneError names the file and what is wrong: the line of a
    syntax error, a file that is no regular file (a FIFO or /dev/zero would never end), larger
    than ``MAX_SCENE_BYTES`` or nested deeper than ``MAX_SCENE_DEPTH``."""
    raw = _read_bounded(path)
    try:
        return checked_depth(path, tomllib.loads(raw.decode("utf-8")))
    except UnicodeDecodeError as exc:
        raise SceneError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except tomllib.TOMLDecodeError as exc:
        # tomllib says "... (at line L, column C)": keep it, it is what the user needs.
        raise SceneError(f"{path}: TOML syntax error: {exc}") from None
    except RecursionError:  # inline tables or arrays nested hundreds deep
        raise SceneError(f"{path}: nested more than {MAX_SCENE_DEPTH} levels deep (tables and arrays)") from None


def _read_bounded(path: Path) -> bytes:
    """The bytes of the regular file ``path``, at most ``MAX_SCENE_BYTES`` of them."""
    return read_input_file(path, MAX_SCENE_BYTES, "scene file", SceneError)


def read_input_file(path: Path, max_bytes: int, what: str, error: type[LegsimError] = SceneError) -> bytes:
    """The bytes of ``path``, a file a run reads (a scene, a URDF, a mesh): ``error`` naming the
    file and ``what`` it should be when it is missing, no regular file (a folder, a FIFO or a
    device: reading /dev/zero would never end, opening a FIFO would wait for a writer), unreadable
    or larger than ``max_bytes`` (bytes)."""
    try:
        # O_NONBLOCK: opening a FIFO must not wait for a writer before fstat can refuse it.
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise error(f"{path}: no such {what}") from None
    except OSError as exc:
        raise error(f"{path}: cannot read the {what}: {exc.strerror or exc}") from None
    with os.fdopen(fd, "rb") as fh:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise error(f"{path}: not a {what} (it is {file_kind(mode)})")
        try:
            raw = fh.read(max_bytes + 1)
        except OSError as exc:
            raise error(f"{path}: cannot read the {what}: {exc.strerror or exc}") from None
    if len(raw) > max_bytes:
        raise error(f"{path}: larger than {max_bytes} bytes, the most a {what} may hold")
    return raw


def inside_folder(folder: Path, value: str) -> Path | None:
    """The file ``value`` names (relative to ``folder``, or absolute), links resolved, when it
    lies inside ``folder`` (links resolved too); None when it leads out of it."""
    real_folder = os.path.realpath(folder)
    real = os.path.realpath(os.path.join(folder, value))
    if os.path.commonpath([real_folder, real]) != real_folder:
        return None
    return Path(real)


def scene_relative_files(path: Path, schema: Mapping[str, Param], params: dict[str, Any], where: str) -> None:
    """File parameters (``Param(path=True)``) resolved against the scene's folder, in place.
    A scene may come from someone else: the file must lie inside that folder (links resolved,
    as for its ``[output]`` paths), and be a regular file. SceneError naming the field otherwise."""
    for name, param in schema.items():
        value = params.get(name)
        if not param.path or not isinstance(value, str) or not value:
            continue
        field = f"{where}.{name}"
        if "\x00" in value:
            raise field_error(path, field, f"{value!r} contains a NUL character")
        file = inside_folder(path.parent, os.path.expanduser(value))
        if file is None:
            raise field_error(
                path,
                field,
                f"{value!r} lies outside the scene's folder {path.parent}; a scene reads files only "
                f"from its own folder (links resolved)",
            )
        try:
            mode = os.stat(file).st_mode
        except FileNotFoundError:
            raise field_error(
                path, field, f"no such file {value!r} (a relative path is read from the scene's folder {path.parent})"
            ) from None
        except OSError as exc:
            raise field_error(path, field, f"{value!r} cannot be read: {exc.strerror or exc}") from None
        if not stat.S_ISREG(mode):
            raise field_error(path, field, f"{value!r} is not a file: it is {file_kind(mode)}")
        params[name] = str(file)


def checked_depth(path: Path, data: dict[str, Any]) -> dict[str, Any]:
    """``data`` when its tables and arrays nest at most ``MAX_SCENE_DEPTH`` deep (dotted keys
    nest without brackets, so the parsed content is measured); SceneError otherwise."""
    level: list[dict[str, Any] | list[Any]] = [data]
    for _ in range(MAX_SCENE_DEPTH + 1):
        level = [
            child
            for node in level
            for child in (node.values() if isinstance(node, dict) else node)
            if isinstance(child, (dict, list))
        ]
        if not level:
            return data
    raise SceneError(f"{path}: nested more than {MAX_SCENE_DEPTH} levels deep (tables and arrays)")


def scene_info(path: Path) -> dict[str, Any]:
    """Name, robot and description of a scene file, read without building its model
    (for listings); ``error`` holds the reason when the file cannot be read."""
    info: dict[str, Any] = {"name": path.stem, "robot": None, "description": "", "path": str(path)}
    try:
        data = read_toml(path)
    except SceneError as exc:
        info["error"] = str(exc)
        return info
    scene_t = data.get("scene")
    robot_t = data.get("robot")
    scene_t = scene_t if isinstance(scene_t, dict) else {}
    robot_t = robot_t if isinstance(robot_t, dict) else {}
    if isinstance(scene_t.get("description"), str):
        info["description"] = scene_t["description"]
    if isinstance(robot_t.get("name"), str):
        info["robot"] = robot_t["name"]
    return info
