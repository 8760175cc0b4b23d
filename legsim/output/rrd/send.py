"""Sending a recording file to a running Rerun viewer, as a child process of ``legsim run
--connect`` (``legsim.output.rrd.live.stream_rrd``).

Rerun's client waits for a viewer without a deadline: when the viewer accepts the connection
and then never takes the data, its ``disconnect`` and the interpreter's exit block forever, and
SIGTERM is not handled while they do. Run here, in a process of its own, that wait is one the
parent can end: it waits with a deadline, in slices short enough to handle Ctrl-C and SIGTERM,
and kills this process when the deadline passes.

``python -m legsim.output.rrd.send URL FILE LAYOUT``: the chunks of the recording FILE (written
by ``write_rrd``) to the viewer at URL, then the blueprint made from LAYOUT (the JSON of
``write.record``'s layout). Exit 0 once the viewer has taken everything.
"""

from __future__ import annotations

import json
import sys
import uuid
from collections.abc import Sequence
from typing import Any

import numpy as np


def layout_json(layout: Any) -> str:
    """``write.record``'s layout as the JSON this program reads."""
    groups, box = layout
    return json.dumps(
        {
            "groups": [[g.unit, g.title, list(g.entities)] for g in groups],
            "box": None if box is None else [np.asarray(corner, dtype=float).tolist() for corner in box],
        }
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Send FILE to URL (module docstring); the exit code."""
    import rerun as rr
    import rerun.blueprint as rrb
    from rerun.chunk import RrdReader

    from .layout import APPLICATION_ID
    from .views import UnitGroup, blueprint

    url, file, layout = list(sys.argv[1:] if argv is None else argv)
    data = json.loads(layout)
    groups = [UnitGroup(unit, title, tuple(entities)) for unit, title, entities in data["groups"]]
    corners = data["box"]
    box = None if corners is None else (np.array(corners[0], dtype=float), np.array(corners[1], dtype=float))
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=uuid.uuid4())
    rec.connect_grpc(url)
    rec.send_chunks(RrdReader(file).stream())
    rec.send_blueprint(blueprint(rrb, groups, box))
    rec.flush()
    rec.disconnect()  # returns once the viewer has taken everything
    return 0


if __name__ == "__main__":
    sys.exit(main())
