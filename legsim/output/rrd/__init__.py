"""Rerun recordings of runs (``.rrd``): ``write_rrd`` records a run headlessly, ``read_rrd``
reads it back with Rerun's own reader.

* ``layout``: the format name, timelines, entity tree and colours of a recording.
* ``write``: ``write_rrd``, the logging of each entity, and the thinning to a rate.
* ``bodies``: each body's shape logged once and a Transform3D per sample; ``poses`` the
  fitting of a shape's pose to each polyline the model draws.
* ``urdf``: a URDF robot through Rerun's own URDF loader, moved by joint and root transforms.
* ``stream``: the run's samples a chunk at a time, thinned to a rate, for the writer.
* ``views``: the plot views grouped by unit and the blueprint the viewer opens on.
* ``live``: ``stream_rrd`` to a spawned or running viewer (``legsim run --spawn/--connect``).
* ``send``: the child process ``--connect`` sends a recording file through, with a deadline.
* ``digest``: the digest of what legsim logged and the seal of a file, verified by ``read_rrd``.
* ``read``: ``read_rrd``, which assembles the recorded rows into numbers; ``columns`` the
  reader of the recorded components per entity; ``frames`` the robot back as polylines.

rerun is imported inside the functions only: importing this package costs nothing.
"""

from .layout import FORMAT
from .read import read_rrd
from .write import write_rrd

__all__ = ["FORMAT", "read_rrd", "write_rrd"]
