"""Sweeps: many variations of one scene run on Dask, one table row per variation.

::

    import legsim
    result = legsim.sweep("compass_gait", grid={"initial.state.stanced": (0.6, 1.6, 101),
                                                "initial.state.hipd": (-2.0, 0.5, 101)},
                          walk=True, out="basin")
    result.table            # a pyarrow Table, also in basin/results.parquet
    result.counts("outcome")

Modules, in the order a sweep uses them:

* ``spec``: ``SweepSpec``, the variations (grids and random draws over any scene field) and the
  measures; parsing of ``--grid`` and ``--random``.
* ``engine``: ``Engine``, Dask (embedded local cluster or a running scheduler) or this process,
  running batches of variations and handing each back as it finishes.
* ``tasks``: what a worker does with a batch: one row per variation, errors and timeouts
  included.
* ``walk``: a gait's scene walked step by step until it falls or converges (basins of attraction).
* ``table``: the Parquet table streamed to disk, ``--resume``.
* ``runner``: ``run_sweep``, the whole sweep; ``SweepResult``.
* ``stochastic``: the samples of ``legsim stochastic`` on the same engine.

The package itself is callable: ``legsim.sweep(...)`` is ``legsim.sweep.sweep(...)``. Dask,
pyarrow and rich are imported when a sweep runs, not when legsim is imported.
"""

from __future__ import annotations

import math
import sys
import types
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any


def sweep(
    scene: str | Path,
    *,
    grid: Mapping[str, Any] | None = None,
    random: Mapping[str, tuple[float, float]] | None = None,
    samples: int = 1,
    seed: int = 0,
    overrides: Sequence[str] = (),
    run: bool = True,
    walk: bool = False,
    orbit: bool = False,
    max_steps: int = 20,
    tol: float = 1e-3,
    timeout: float | None = None,
    measures: Sequence[str] = (),
    orbit_guess: str = "scene",
    out: str | Path | None = None,
    resume: bool = False,
    workers: int | None = None,
    scheduler: str | None = None,
    in_process: bool = False,
    batch_size: int | None = None,
    progress: bool = False,
    figures: bool = True,
    connect_timeout: float | None = None,
) -> Any:
    """Run variations of a scene and return a ``SweepResult`` (its ``table`` has one row each).

    Parameters
    ----------
    scene: a scene file or bundled scene name; ``overrides``: ``key.path=value`` strings
        applied to every variation first (as ``--set``).
    grid: scene field (dotted path, e.g. ``"initial.state.thetad"``) -> ``(low, high, n)`` (n
        values from low to high, both included) or a list of values. Several fields make the
        Cartesian product, the first varying slowest.
    random: field -> ``(low, high)``: ``samples`` uniform draws in [low, high) seeded by
        ``seed`` (every grid cell is run with every draw).
    run: run the scene to its t_final and keep its summary; ``walk``: instead walk it step by
        step until it falls, stops or converges onto the scene's gait (its ``[orbit]``
        section), at most ``max_steps`` steps, converged within ``tol`` (state units);
        ``orbit``: also search each variation's periodic orbit (multipliers, stability).
    timeout: seconds one variation may take; past it its row says ``timeout``.
    measures: ``"KIND:COORD[:FROM]"`` strings (``--measure``), each a float column of the runs:
        ``mean_rate:x:5`` the mean rate of x over [5 s, t_end], ``max_abs:pitch`` the largest
        |pitch| (``legsim.sweep.measures``).
    orbit_guess: ``"scene"`` (the scene's ``[initial]`` state and ``orbit.guess``) or ``"run"``
        (the state and controller memory at the last crossing of the section in the run).
    out: folder for ``results.parquet`` (streamed as batches finish) and the maps; None keeps
        the table in memory only. ``resume``: continue the sweep already in ``out``, running
        only the variations it has no row for.
    workers: size of the embedded Dask cluster (default: one process per core);
        ``scheduler``: address of a running Dask scheduler instead (default: the
        ``DASK_SCHEDULER_ADDRESS`` environment variable); ``in_process``: no Dask, run here.
    batch_size: variations per task (default: sized to about 2 s of work each).
    progress: draw a progress bar (done / total, ETA) on stderr when it is a terminal.
    figures: with ``out`` and a two-field grid, draw the basin map (walks) and the stability
        map (orbits) into ``out``.
    connect_timeout: seconds to wait at each step of reaching ``scheduler`` (default 20).
    """
    from .runner import run_sweep
    from .spec import Axis, SweepSpec, check_count, parse_grid, scene_reference

    # Counted before any grid's values are made: a grid of 10^9 values is refused at once.
    check_count([_grid_length(value) for value in (grid or {}).values()], samples if random else 1)
    axes = tuple(_grid_axis(key, value, parse_grid, Axis) for key, value in (grid or {}).items())
    draws = tuple(_random_axis(key, value, Axis) for key, value in (random or {}).items())
    kind = "walk" if walk else ("scene" if run else "none")
    spec = SweepSpec(
        scene=scene_reference(scene),
        overrides=tuple(overrides),
        grid=axes,
        random=draws,
        samples=samples if draws else 1,
        seed=seed,
        run=kind,
        orbit=orbit,
        max_steps=max_steps,
        tol=tol,
        timeout=timeout,
        measures=tuple(measures),
        orbit_guess=orbit_guess,
    )
    return run_sweep(
        spec,
        out=out,
        resume=resume,
        workers=workers,
        scheduler=scheduler,
        in_process=in_process,
        batch_size=batch_size,
        progress=progress,
        figures=figures,
        connect_timeout=connect_timeout,
    )


def _grid_length(value: Any) -> int:
    """How many values a ``grid`` entry names (``_grid_axis`` refuses what is no grid)."""
    if isinstance(value, tuple) and len(value) == 3 and all(isinstance(v, (int, float)) for v in value):
        n = value[2]
        return int(n) if isinstance(n, (int, float)) and not isinstance(n, bool) and 1 <= n < 2**62 else 1
    return len(value) if isinstance(value, (list, tuple)) and value else 1


def _numbers(value: Any, count: int) -> bool:
    """Whether ``value`` is a tuple of ``count`` real numbers (no booleans)."""
    return (
        isinstance(value, tuple)
        and len(value) == count
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
    )


def _grid_axis(key: str, value: Any, parse: Any, axis: Any) -> Any:
    """A ``grid`` entry: a tuple is a range (low, high, n), a list holds the values."""
    from .spec import SweepError

    if _numbers(value, 3):
        low, high, n = value
        return parse(f"{key}={low!r}:{high!r}:{n!r}")
    if isinstance(value, list) and value:
        return axis(key, tuple(value))
    raise SweepError(
        f"grid {key}: expected a range (low, high, n) or a non-empty list of values, got {value!r} (a tuple is "
        f"read as a range: give a list for values)"
    )


def _random_axis(key: str, value: Any, axis: Any) -> Any:
    """A ``random`` entry: (low, high), finite, low < high."""
    from .spec import SweepError

    if not (_numbers(value, 2) and all(math.isfinite(v) for v in value) and value[0] < value[1]):
        raise SweepError(f"random {key}: expected (low, high) with finite low < high, got {value!r}")
    return axis(key, (), float(value[0]), float(value[1]))


class _CallableModule(types.ModuleType):
    """``legsim.sweep(...)`` calls ``sweep``; the module's names stay reachable as attributes."""

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return sweep(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule

__all__ = ["sweep"]
