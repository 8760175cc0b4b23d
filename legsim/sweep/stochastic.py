"""``legsim stochastic --samples N`` on the sweep engine: the executions of a Monte Carlo run
drawn in batches on Dask workers.

Execution k draws from its own generator (``legsim.stochastic.sample_generator(seed, k)``), so
a batch of executions drawn on any worker is the same as those executions drawn in one
process: the ensemble, and every number of its summary, is the serial one.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ..stochastic import Ensemble


@dataclass(frozen=True)
class SampleJob:
    """What a worker needs to draw executions: the scene (name or absolute path), its ``--set``
    overrides and the ``[stochastic]`` settings given on the command line."""

    scene: str
    overrides: tuple[str, ...]
    settings: tuple[tuple[str, Any], ...]


def sample_batch(job: SampleJob, indices: list[int]) -> list[tuple[dict[str, Any], Any]]:
    """Executions ``indices`` of the scene's ensemble, each with the ensemble's settings."""
    from ..scene import load_scene
    from ..scene.stochastic import ensemble_from_scene

    scene = load_scene(job.scene, list(job.overrides))
    ensemble = ensemble_from_scene(scene, dict(job.settings), indices=indices)
    return [(ensemble.settings, execution) for execution in ensemble.executions]


def ensemble_on_engine(
    scene: Any,
    scene_ref: str,
    settings: dict[str, Any],
    engine: Any,
    progress: Callable[[int, int], None] | None = None,
) -> Ensemble:
    """The ensemble of a loaded ``scene`` (``scene_ref``: how workers load it) with the
    command line's ``[stochastic]`` settings, its executions drawn on ``engine``
    (``legsim.sweep.engine.Engine``, entered). A batch that fails on its worker raises."""
    from ..scene.stochastic import scene_settings

    resolved = scene_settings(scene, settings)
    samples = resolved["samples"]
    job = SampleJob(
        scene_ref, tuple(scene.overrides), tuple(sorted((k, v) for k, v in settings.items() if v is not None))
    )
    drawn: dict[int, Any] = {}

    def on_done(batch: list[int], results: Any) -> None:
        if isinstance(results, BaseException):
            raise results
        drawn.update(zip(batch, results, strict=True))
        if progress is not None:
            progress(len(drawn), samples)

    engine.run(sample_batch, job, list(range(samples)), on_done)
    return Ensemble([drawn[k][1] for k in range(samples)], drawn[0][0])
