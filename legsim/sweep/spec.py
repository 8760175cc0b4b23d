"""What a sweep runs: the scene, its variations (grids and random draws over scene fields) and
the measures asked of every run, as one JSON-ready ``SweepSpec`` that is stored beside the
results (``sweep.json``) so that ``--resume`` can check it is continuing the same sweep.

Variations
----------
A variation sets scene fields by their dotted path, exactly as ``--set`` does
(``initial.state.thetad``, ``robot.parameters.slope``, ``integrator.h``):

* ``grid``: ``KEY=LO:HI:N`` (N values evenly spaced from LO to HI, both included) or
  ``KEY=V1,V2,...`` (the values listed, read as TOML literals). Several grids make the
  Cartesian product, the first axis varying slowest.
* ``random``: ``KEY=LO:HI`` drawn uniformly in [LO, HI), ``samples`` draws from a numpy
  generator seeded by ``seed``. With grids too, every grid cell is run with every draw (the
  draws are shared: common random numbers).

Variation ``index`` (0-based, the table's ``index`` column) is ``cell * samples + draw``.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import tomllib
from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..output.untrusted import check_list, check_object
from .errors import SweepError
from .measures import check_measures

#: Most variations of one sweep: each is a row held in memory while the table is assembled.
MAX_VARIATIONS = 10_000_000

#: What a row's run is: the scene to its t_final, a walk until it falls or converges, or none.
RUN_KINDS = ("scene", "walk", "none")
#: Where an orbit search's initial guess comes from: the scene, or the variation's run.
ORBIT_GUESSES = ("scene", "run")


@dataclass(frozen=True)
class Axis:
    """One varied scene field: ``key`` (dotted path) and its grid ``values``, or for a random
    axis the interval ``[low, high)``."""

    key: str
    values: tuple[Any, ...] = ()
    low: float | None = None
    high: float | None = None

    @property
    def is_random(self) -> bool:
        return self.low is not None


@dataclass(frozen=True)
class SweepSpec:
    """A sweep, complete: everything its rows depend on.

    scene: the scene file (absolute path) or bundled name; overrides: ``--set`` strings applied
    to every variation first; grid, random: the axes; samples, seed: the random draws;
    run: one of ``RUN_KINDS``; orbit: search each variation's periodic orbit; max_steps and
    tol: a walk's step budget and its convergence tolerance (state units); timeout: seconds
    one variation may take (None: no limit); measures: ``KIND:COORD[:FROM]`` strings, each a
    column of the run (``legsim.sweep.measures``); orbit_guess: one of ``ORBIT_GUESSES``, the
    orbit search's guess: the scene's (``[initial]`` and ``orbit.guess``) or the last crossing of
    the section in the variation's run; inputs: the SHA-256 (hex) of the files the scene reads
    (the scene file, its URDF, its terrain CSV: ``inputs_digest``) when the sweep began, so that
    ``--resume`` refuses a sweep whose files have changed since ("" where none was taken).
    """

    scene: str
    overrides: tuple[str, ...] = ()
    grid: tuple[Axis, ...] = ()
    random: tuple[Axis, ...] = ()
    samples: int = 1
    seed: int = 0
    run: str = "scene"
    orbit: bool = False
    max_steps: int = 20
    tol: float = 1e-3
    timeout: float | None = None
    measures: tuple[str, ...] = ()
    orbit_guess: str = "scene"
    inputs: str = ""
    _draws: Any = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        check_spec(self)

    # -- the variations -------------------------------------------------------------------
    @property
    def keys(self) -> tuple[str, ...]:
        """The varied fields, grid axes first."""
        return tuple(a.key for a in self.grid + self.random)

    @property
    def cells(self) -> int:
        return math.prod(len(a.values) for a in self.grid)

    def __len__(self) -> int:
        return self.cells * (self.samples if self.random else 1)

    def values(self, index: int) -> dict[str, Any]:
        """The field values of variation ``index``: key -> value."""
        draws = self.samples if self.random else 1
        cell, draw = divmod(index, draws)
        out: dict[str, Any] = {}
        for axis in reversed(self.grid):
            cell, k = divmod(cell, len(axis.values))
            out[axis.key] = axis.values[k]
        out = {a.key: out[a.key] for a in self.grid}
        if self.random:
            row = self.draws()[draw]
            out.update({a.key: float(v) for a, v in zip(self.random, row, strict=True)})
        return out

    def draws(self) -> np.ndarray:
        """The random draws, shape (samples, len(random)), made once."""
        if self._draws is None:
            rng = np.random.default_rng(self.seed)
            low = np.array([a.low for a in self.random])
            high = np.array([a.high for a in self.random])
            object.__setattr__(self, "_draws", rng.uniform(low, high, size=(self.samples, len(self.random))))
        return self._draws

    def items(self, indices: Sequence[int] | None = None) -> Iterator[tuple[int, dict[str, Any]]]:
        """(index, values) of the variations, all of them or those of ``indices``."""
        for index in range(len(self)) if indices is None else indices:
            yield index, self.values(index)

    # -- persistence --------------------------------------------------------------------------
    def to_json(self) -> dict[str, Any]:
        """The sweep as a JSON document (tuples as lists), which ``from_json`` reads back."""
        out = asdict(self)
        out.pop("_draws")
        # A sweep without these keeps the manifest and digest it had before they existed.
        if not out["measures"]:
            out.pop("measures")
        if out["orbit_guess"] == "scene":
            out.pop("orbit_guess")
        if not out["inputs"]:
            out.pop("inputs")
        result: dict[str, Any] = json.loads(json.dumps(out, allow_nan=False))
        return result

    @classmethod
    def from_json(cls, data: Any) -> SweepSpec:
        """The sweep of a ``to_json`` document read back (a manifest, which may be damaged or
        foreign): ValueError naming the key for anything of the wrong type, SweepError for an
        inconsistent sweep."""
        check_object(data, SPEC_KEYS, "spec", optional=OPTIONAL_SPEC_KEYS)
        unknown = sorted(set(data) - set(SPEC_KEYS) - set(OPTIONAL_SPEC_KEYS))
        if unknown:
            raise ValueError(f"spec has unknown keys {unknown}")
        check_list(data["overrides"], (str,), "spec.overrides")
        axes = {}
        for kind in ("grid", "random"):
            axes[kind] = tuple(_axis_from_json(a, f"spec.{kind}[{k}]") for k, a in enumerate(data[kind]))
        if any(a.is_random for a in axes["grid"]) or not all(a.is_random for a in axes["random"]):
            raise ValueError("spec: a grid axis has an interval, or a random axis has none")
        measures = tuple(check_list(data.get("measures", []), (str,), "spec.measures"))
        return cls(**{**data, **axes, "overrides": tuple(data["overrides"]), "measures": measures})

    def with_inputs(self, files: Sequence[os.PathLike[str] | str]) -> SweepSpec:
        """This sweep with ``inputs`` the digest of ``files`` as they are now."""
        return replace(self, inputs=inputs_digest(files))

    def fingerprint(self) -> str:
        """The SHA-256 (hex) of everything the rows depend on: ``--resume`` continues only the
        sweep whose manifest and table carry it."""
        text = json.dumps(self.to_json(), sort_keys=True, allow_nan=False)
        return hashlib.sha256(text.encode()).hexdigest()


def inputs_digest(files: Sequence[os.PathLike[str] | str]) -> str:
    """The SHA-256 (hex) of the files' names and contents, in order: what a sweep's rows
    depend on beyond its specification. SweepError naming a file that cannot be read."""
    digest = hashlib.sha256()
    for file in files:
        path = Path(file)
        try:
            content = path.read_bytes()
        except OSError as exc:
            raise SweepError(f"{path}: cannot read this input of the sweep's scene: {exc.strerror or exc}") from None
        digest.update(f"{path.name}\0{len(content)}\0".encode())
        digest.update(content)
    return digest.hexdigest()


#: The keys of a sweep's ``to_json`` document and their JSON types.
SPEC_KEYS: dict[str, tuple[type, ...]] = {
    "scene": (str,),
    "overrides": (list,),
    "grid": (list,),
    "random": (list,),
    "samples": (int,),
    "seed": (int,),
    "run": (str,),
    "orbit": (bool,),
    "max_steps": (int,),
    "tol": (int, float),
}
OPTIONAL_SPEC_KEYS: dict[str, tuple[type, ...]] = {
    "timeout": (int, float, type(None)),
    "measures": (list,),
    "orbit_guess": (str,),
    "inputs": (str,),
}
AXIS_KEYS: dict[str, tuple[type, ...]] = {
    "key": (str,),
    "values": (list,),
    "low": (int, float, type(None)),
    "high": (int, float, type(None)),
}


def _axis_from_json(data: Any, where: str) -> Axis:
    check_object(data, AXIS_KEYS, where)
    if sorted(data) != sorted(AXIS_KEYS):
        raise ValueError(f"{where} has keys {sorted(data)}, expected {sorted(AXIS_KEYS)}")
    values = check_list(data["values"], (bool, int, float, str), f"{where}.values")
    if (data["low"] is None) != (data["high"] is None) or (data["low"] is None and not values):
        raise ValueError(f"{where}: an axis has values, or an interval low..high")
    return Axis(data["key"], tuple(values), data["low"], data["high"])


def check_spec(spec: SweepSpec) -> None:
    """SweepError naming the option for anything inconsistent."""
    if spec.run not in RUN_KINDS:
        raise SweepError(f"run must be one of {list(RUN_KINDS)}, got {spec.run!r}")
    if spec.run == "none" and not spec.orbit:
        raise SweepError("nothing to measure: the run is 'none' (--no-run) and no --orbit is asked for")
    if spec.orbit_guess not in ORBIT_GUESSES:
        raise SweepError(f"--orbit-guess must be one of {list(ORBIT_GUESSES)}, got {spec.orbit_guess!r}")
    if spec.orbit_guess == "run" and not (spec.orbit and spec.run == "scene"):
        raise SweepError("--orbit-guess run needs --orbit and runs to t_final (not with --walk or --no-run)")
    if spec.measures:
        if spec.run != "scene":
            raise SweepError("--measure needs runs to t_final (not with --walk or --no-run)")
        check_measures(spec.measures)
    keys = [a.key for a in spec.grid + spec.random]
    repeated = sorted({k for k in keys if keys.count(k) > 1})
    if repeated:
        raise SweepError(f"--grid/--random: field(s) {repeated} varied twice")
    if isinstance(spec.samples, bool) or not isinstance(spec.samples, int) or spec.samples < 1:
        raise SweepError(f"--samples must be an integer >= 1, got {spec.samples!r}")
    if isinstance(spec.seed, bool) or not isinstance(spec.seed, int) or spec.seed < 0:
        raise SweepError(f"--seed must be an integer >= 0, got {spec.seed!r}")
    if isinstance(spec.max_steps, bool) or not isinstance(spec.max_steps, int) or spec.max_steps < 1:
        raise SweepError(f"--max-steps must be an integer >= 1, got {spec.max_steps!r}")
    if not (isinstance(spec.tol, (int, float)) and math.isfinite(spec.tol) and spec.tol > 0):
        raise SweepError(f"--tol must be a finite number > 0, got {spec.tol!r}")
    if spec.timeout is not None and not (
        isinstance(spec.timeout, (int, float)) and math.isfinite(spec.timeout) and spec.timeout > 0
    ):
        raise SweepError(
            f"--timeout must be a finite number of seconds > 0 (omit it for no limit), got {spec.timeout!r}"
        )
    for axis in spec.grid:
        for value in axis.values:
            if not isinstance(value, (bool, int, float, str)) or (
                isinstance(value, float) and not math.isfinite(value)
            ):
                raise SweepError(f"--grid {axis.key}: {value!r} is not a finite number, a string or a boolean")
            if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 2**63:
                raise SweepError(f"--grid {axis.key}: {value!r} is beyond the 64-bit integers of the table")
    for axis in spec.random:
        if not (axis.low is not None and axis.high is not None and math.isfinite(axis.low) and axis.high > axis.low):
            raise SweepError(f"--random {axis.key}: LO and HI must be finite numbers with HI > LO")
        if not math.isfinite(axis.high):
            raise SweepError(f"--random {axis.key}: LO and HI must be finite numbers with HI > LO")
    check_count([len(a.values) for a in spec.grid], spec.samples if spec.random else 1)


def check_count(sizes: Sequence[int], samples: int = 1) -> int:
    """The number of variations of grids of ``sizes`` values with ``samples`` draws each, or
    SweepError past ``MAX_VARIATIONS``: counted before any value is made, so that an absurd grid
    is refused at once, without the memory its values would take."""
    count = max(1, samples)
    for size in sizes:
        count *= size
        if count > MAX_VARIATIONS:
            break
    if count > MAX_VARIATIONS or any(size < 1 for size in sizes):
        shape = " x ".join(str(n) for n in [*sizes, *([samples] if samples > 1 else [])])
        raise SweepError(f"{shape} variations, more than the limit {MAX_VARIATIONS:.0e}: check the grid sizes")
    return count


def grid_size(text: str) -> int:
    """How many values ``--grid TEXT`` names, read without making them (``KEY=LO:HI:N``: N;
    ``KEY=V1,V2,...``: the count of the list)."""
    _, raw = _split(text, "--grid", "KEY=LO:HI:N or KEY=V1,V2,...")
    if ":" not in raw:
        return raw.count(",") + 1
    parts = raw.split(":")
    if len(parts) != 3:
        raise SweepError(f"--grid {text!r}: expected KEY=LO:HI:N, e.g. initial.state.thetad=-2:2:101")
    n = _number(parts[2], text, "--grid")
    if not float(n).is_integer() or n < 1:
        raise SweepError(f"--grid {text!r}: N must be an integer >= 1, got {parts[2]}")
    return int(n)


# -- parsing the command line's axes ----------------------------------------------------------
def parse_grid(text: str) -> Axis:
    """``KEY=LO:HI:N`` or ``KEY=V1,V2,...`` into an Axis (values in scene units)."""
    key, raw = _split(text, "--grid", "KEY=LO:HI:N or KEY=V1,V2,...")
    n = check_count([grid_size(text)])
    if ":" in raw:
        parts = raw.split(":")
        low, high = (_number(p, text, "--grid") for p in parts[:2])
        grid = np.linspace(low, high, n) if n > 1 else np.array([low])
        if isinstance(low, int) and isinstance(high, int) and np.all(grid == np.round(grid)):
            return Axis(key, tuple(int(v) for v in grid))
        return Axis(key, tuple(float(v) for v in grid))
    values = tuple(_literal(v.strip(), text) for v in raw.split(","))
    if any(v == "" for v in values):
        raise SweepError(f"--grid {text!r}: an empty value in the list")
    return Axis(key, values)


def parse_random(text: str) -> Axis:
    """``KEY=LO:HI`` into a random Axis, drawn uniformly in [LO, HI)."""
    key, raw = _split(text, "--random", "KEY=LO:HI")
    parts = raw.split(":")
    if len(parts) != 2:
        raise SweepError(f"--random {text!r}: expected KEY=LO:HI, e.g. robot.parameters.slope=2:5")
    low, high = (float(_number(p, text, "--random")) for p in parts)
    if not high > low:
        raise SweepError(f"--random {text!r}: HI must be > LO")
    return Axis(key, (), low, high)


def _split(text: str, option: str, form: str) -> tuple[str, str]:
    if not isinstance(text, str) or "=" not in text:
        raise SweepError(f"{option} {text!r}: expected {form}")
    key, raw = (s.strip() for s in text.split("=", 1))
    if not key or any(not p.strip() for p in key.split(".")):
        raise SweepError(f"{option} {text!r}: the key must be a dotted path of scene fields, e.g. initial.state.x")
    return key, raw


def _number(raw: str, text: str, option: str) -> int | float:
    value = _literal(raw.strip(), text)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise SweepError(f"{option} {text!r}: {raw.strip()!r} is not a finite number")
    return value


def _literal(raw: str, text: str) -> Any:
    try:
        return tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        return raw


def override(key: str, value: Any) -> str:
    """``key=value`` as ``--set`` reads it, the value exact (floats by ``repr``, which
    round-trips, and TOML reads back bit for bit)."""
    if isinstance(value, bool):
        return f"{key}={'true' if value else 'false'}"
    if isinstance(value, float):
        # float(): a numpy scalar (a float subclass) would otherwise give "np.float64(0.5)".
        text = (
            repr(float(value))
            if math.isfinite(value)
            else ("nan" if value != value else ("inf" if value > 0 else "-inf"))
        )
        return f"{key}={text}"
    if isinstance(value, int):
        return f"{key}={value}"
    if isinstance(value, str):
        return f"{key}={json.dumps(value)}"
    raise SweepError(f"{key}: cannot vary a field over {type(value).__name__} values")


def variation_overrides(values: dict[str, Any]) -> list[str]:
    """The ``--set`` strings of one variation's values."""
    return [override(k, v) for k, v in values.items()]


def scene_reference(scene: str | os.PathLike[str]) -> str:
    """A scene as the workers will load it: a bundled scene by its name (found in each
    worker's own installation), any other by its absolute path (which workers on other hosts
    must see at the same place, e.g. on a shared file system)."""
    from ..scene import bundled_dir, resolve_scene_path

    path = resolve_scene_path(scene).resolve()
    if path.parent == bundled_dir().resolve():
        return path.stem
    return str(path)


def _ends(axis: Axis) -> tuple[Any, Any]:
    """A grid axis's first and last values; a random axis's LO and the value just under HI."""
    if axis.low is None or axis.high is None:
        return axis.values[0], axis.values[-1]
    return axis.low, float(np.nextafter(axis.high, axis.low))


def _checked_values(axis: Axis) -> tuple[Any, ...]:
    """The values of an axis whose loading checks the whole axis: its ends (``_ends``) where
    its values are numbers in order, a random axis's always (the values between the ends are in
    a field's range where the ends are), else each of its values."""
    if axis.low is not None and axis.high is not None:
        return _ends(axis)
    values = list(axis.values)
    numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)
    if numbers and values in (sorted(values), sorted(values, reverse=True)):
        return _ends(axis)
    distinct: list[Any] = []
    for v in values:
        if v not in distinct:
            distinct.append(v)
    return tuple(distinct)


def corners(spec: SweepSpec) -> Iterator[dict[str, Any]]:
    """Variations at the axes' ends (grid: first and last value, or every value of an axis of
    values not in order; random: LO and a value just under HI), the other axes at their first
    value: loading them checks every axis's range before the sweep starts. The first one has
    every axis at its first value."""
    checked = [_checked_values(a) for a in spec.grid + spec.random]
    first = [values[0] for values in checked]
    yield dict(zip(spec.keys, first, strict=True))
    for k, values in enumerate(checked):
        for value in values[1:]:
            yield dict(zip(spec.keys, [*first[:k], value, *first[k + 1 :]], strict=True))
