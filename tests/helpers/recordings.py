"""A recorded run for the recording, summary and replay tests: the hopper of ``models``
bouncing for 1.5 s (several hops, modes of different dimensions, geometry and energy)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from legsim.output.rrd import read_rrd, write_rrd
from legsim.relaxed import simulate

from .models import hopper_model


def run_hopper(t_final: float = 1.5, eps: float = 2e-3):
    """(model, execution) of the hopper dropped from z = 0.5 m at h = 1e-3 s."""
    model = hopper_model()
    ex = simulate(model.system, np.array([0.5, 0.0]), "flight", t_final, 1e-3, eps)
    return model, ex


def recorded_hopper(folder: Path):
    """(model, execution, path, read_rrd(path)) of ``run_hopper()`` recorded in ``folder``."""
    model, ex = run_hopper()
    assert ex.status == "finished" and len(ex.transitions) >= 4  # the tests need several hops
    path = folder / "hopper.rrd"
    write_rrd(ex, None, path, model=model)
    return model, ex, path, read_rrd(path)


def expected_series(ex) -> dict[str, list[tuple[float, float]]]:
    """Per coordinate, the (time, value) pairs an execution holds, built from its segments
    and strips directly (not through legsim.output): every computed segment point, and each
    strip's held point q at its entry and at its exit."""
    out: dict[str, list[tuple[float, float]]] = {}
    for seg in ex.segments:
        for col, name in enumerate(ex.state_names[seg.mode]):
            out.setdefault(name, []).extend(zip(seg.t.tolist(), seg.x[:, col].tolist(), strict=True))
    for strip in ex.strips:
        for col, name in enumerate(ex.state_names[strip.mode]):
            out.setdefault(name, []).extend([(strip.time, strip.state[col]), (strip.exit_time, strip.state[col])])
    return out
