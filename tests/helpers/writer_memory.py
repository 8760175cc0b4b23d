"""Peak Python memory of the recording writer, measured in an interpreter of its own.

Run as ``python -m helpers.writer_memory DRAWN H_LONG FOLDER``; prints a JSON list of
``[samples, peak bytes]`` for a warm-up, a short and a long run of Example 1 over 2 s. A pytest
worker has threads of its own (xdist's messaging) whose allocations tracemalloc would count in
the writer's peak, so the measurement runs where only the writer allocates.
"""

from __future__ import annotations

import gc
import json
import sys
import tracemalloc
from pathlib import Path

import legsim.output.rrd.write as writer
from legsim.output.rrd import write_rrd
from legsim.scene import load_scene

# Every chunk holds 512 samples. Rerun may keep the arrays it is sent until its sink has written
# them, which the writer waits for every DRAIN_ROWS rows: a smaller wait keeps that share small.
CHUNK = 512
DRAIN_ROWS = 2048


def writer_peak(h: float, path: Path, drawn: bool) -> tuple[int, int]:
    """(samples, peak bytes the writer allocates in Python) of Example 1 over 2 s at step ``h``
    (s), with its drawn robot (``drawn``) or its states only."""
    scene = load_scene("oscillator_ex1", overrides=[f"integrator.h={h}", "integrator.t_final=2.0"])
    ex = scene.simulate()
    gc.collect()
    tracemalloc.start()
    try:
        write_rrd(ex, scene if drawn else None, path)
        return sum(len(seg.t) for seg in ex.segments), tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def main(drawn: bool, h_long: float, folder: Path) -> list[tuple[int, int]]:
    writer.CHUNK = CHUNK
    writer.DRAIN_ROWS = DRAIN_ROWS
    # The warm-up pays rerun's and pyarrow's imports and first-use caches, and the first flush.
    steps = {"warm": 5e-4, "short": 1e-3, "long": h_long}
    return [writer_peak(h, folder / f"{name}.rrd", drawn) for name, h in steps.items()]


if __name__ == "__main__":
    print(json.dumps(main(sys.argv[1] == "drawn", float(sys.argv[2]), Path(sys.argv[3]))))
