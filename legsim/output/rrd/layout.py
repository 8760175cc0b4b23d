"""The layout of a legsim Rerun recording (``.rrd``): format name, timelines, entities, colours.

A recording holds everything needed to inspect a run later without the model:

* ``state/<name>``: every state coordinate by name (Rerun ``Scalars``), one row per *sample*
  (``legsim.output.trace.Trace``): the computed points of every segment and, for every strip,
  its entry and exit with the held state q, in time order. A coordinate only has rows in the
  modes that have it.
* ``samples/t`` (the exact time as float64; the ``sim_time`` timeline only keeps nanoseconds),
  ``strip/active`` (1 inside a strip, 0 outside) and ``mode/index`` (index into the mode list
  of ``legsim/meta``) on the same rows.
* ``mode``: a text log row at the start of every segment (the mode sequence), with its start
  and end times.
* ``events/strips`` and ``events/transitions``: one row per strip (mode, transition name, entry
  and exit times) and per transition (edge, times, depth, state before and after the reset),
  as text for the viewer and as typed values for reading back.
* ``robot/<part>``: the robot's polylines (``Model.geometry``) on frames of the ``frame``
  timeline, drawn in the x-z plane of a z-up 3D view (parts that are one point in every frame
  as points); ``scenery/<part>`` the static ground and stops; ``frames/t`` and
  ``frames/mode`` the exact frame times and modes.
* ``summary`` (markdown for the viewer) and ``legsim/meta`` (JSON: format, run summary with the
  keys of ``legsim run --json``, state names per mode, mode list, geometry part names).

Timelines: ``sim_time`` (simulated time, what the viewer scrubs), ``sample`` (row index of the
state samples) and ``frame`` (row index of the geometry frames).
"""

FORMAT = "legsim-rrd-1"
APPLICATION_ID = "legsim"
TIMELINE = "sim_time"
SAMPLE_TIMELINE = "sample"
FRAME_TIMELINE = "frame"

# Colours (RGB) of robot parts in the viewer, in order of part name; scenery is grey.
PART_COLOURS = [(31, 119, 180), (214, 39, 40), (44, 160, 44), (255, 127, 14), (148, 103, 189),
                (140, 86, 75), (227, 119, 194), (23, 190, 207), (188, 189, 34)]
SCENERY_COLOUR = (110, 110, 110)
