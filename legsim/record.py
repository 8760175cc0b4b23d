"""Rerun recordings of executions (``.rrd``), written headlessly and read back.

The documented public module (docs/recording.md): ``write_rrd(execution, scene, path)`` and
``read_rrd(path)``, with the samples and frames they store. ``legsim run --rrd`` finds its
writer here. The code lives in ``legsim.output`` (``rrd`` for Rerun, ``trace`` for the
samples and frames, ``summary`` for the run summary); rerun is imported only when a recording
is written or read.
"""

from .output.rrd import FORMAT, read_rrd, write_rrd
from .output.summary import run_summary
from .output.trace import (
    DEFAULT_FPS,
    DEFAULT_MAX_FRAMES,
    Frames,
    RecordingError,
    Trace,
    execution_trace,
    frame_times,
    geometry_frames,
    scenery_only,
    trace_series,
)

__all__ = [
    "DEFAULT_FPS",
    "DEFAULT_MAX_FRAMES",
    "FORMAT",
    "Frames",
    "RecordingError",
    "Trace",
    "execution_trace",
    "frame_times",
    "geometry_frames",
    "read_rrd",
    "run_summary",
    "scenery_only",
    "trace_series",
    "write_rrd",
]
