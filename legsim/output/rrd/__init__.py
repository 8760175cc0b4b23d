"""Rerun recordings of runs (``.rrd``): ``write_rrd`` records a run headlessly, ``read_rrd``
reads it back with Rerun's own reader.

* ``layout``: the format name, timelines, entities and colours of a recording.
* ``write``: ``write_rrd``, the logging of each entity and the viewer's blueprint.
* ``read``: ``read_rrd``, which assembles the recorded rows into numbers.
* ``columns``: the reader of the recorded components per entity.

rerun is imported inside the functions only: importing this package costs nothing.
"""

from .layout import FORMAT
from .read import read_rrd
from .write import write_rrd

__all__ = ["FORMAT", "read_rrd", "write_rrd"]
