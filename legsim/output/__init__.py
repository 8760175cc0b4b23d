"""What a run leaves behind: its summary, its files and its recordings.

* ``files``: every output file is written atomically (complete or absent) through
  ``write_atomic`` / ``write_bytes_atomic``, never over an input, a device or another output
  of the run (``OutputPlan``).
* ``execution_file``: ``save_execution`` and ``load_execution`` (a checked ``.npz``).
* ``untrusted``: JSON read with bounded depth, strings printed with control characters escaped.
* ``summary``: ``run_summary``, the one JSON object describing a run (``legsim run --json``).
* ``trace``: the renderer-neutral view of a run: its samples (``Trace``) and the robot's
  geometry at a sequence of times (``Frames``), which the recordings, plots and animations draw.
* ``rrd``: Rerun recordings (``write_rrd``, ``read_rrd``).

Nothing here imports rerun, pyarrow or matplotlib at import time.
"""

from .files import write_atomic, write_bytes_atomic
from .rrd import FORMAT, read_rrd, write_rrd
from .summary import run_summary
from .trace import (
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
    "write_atomic",
    "write_bytes_atomic",
    "write_rrd",
]
