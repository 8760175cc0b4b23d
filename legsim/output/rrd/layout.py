"""The layout of a legsim Rerun recording (``.rrd``, format ``legsim-rrd-2``): timelines, the
entity tree, views and colours.

A recording holds everything needed to inspect a run later without the model. Its rows are
the run's *samples* (``legsim.output.trace.Trace``: every computed point of every segment and,
for every strip, its held guard point q at the entry and at the exit), all of them or, with a
rate, a thinned subset that always keeps each piece's first and last sample (so every
transition's state before and after its reset). Two timelines index them: ``sim_time`` (the
simulated time, what the viewer scrubs) and ``sample`` (the row, 0, 1, ...).

Entity tree::

    /world                       view coordinates: z up; the sagittal plane (x, z) at y = 0
      /scenery/<part>            the ground and stops: LineStrips3D, static
      /robot/<part>              each body's shape in its own frame, logged once (static):
                                 LineStrips3D, or Points3D for a one-point part; moved by a
                                 Transform3D per sample (translation, rotation about y, scale)
      /robot/<robot>/...         a URDF robot instead: Rerun's URDF loader's static geometry,
      /robot/joints/<joint>      moved by a Transform3D per sample per movable joint and for
      /robot/joints/root         the root link in tf#/world (``legsim.output.rrd.urdf``)
    /tf_static                   a URDF robot's joint frames at joint value 0 (the loader's)
    /state/<coordinate>          Scalars per sample in the modes that have the coordinate;
                                 SeriesLines names it with its unit ("x (m)")
    /mode                        StateChange (the mode's name) at each segment's first sample,
                                 with its start and end times; StateConfiguration (colours)
    /strip                       StateChange: the transition's name while its strip holds the
                                 state, reset ("") after it
    /events/transitions          TextLog (INFO) per transition at its strip's entry, with its
                                 fields: name, source, target, edge, index, time, landing_time,
                                 exit_time, depth, state_before, state_after
    /events/strips               TextLog (DEBUG) per strip: mode, name, entry, exit
    /events/warnings             TextLog (WARN) per run warning: kind, time
    /legsim/samples              the exact time of each sample (float64; sim_time keeps ns)
    /legsim/meta                 JSON: format, run summary (keys of ``legsim run --json``),
                                 names and units per mode, the coordinate -> entity map, parts
    /legsim/digest               JSON: the SHA-256 of every component logged above, per entity,
                                 logged last (``legsim.output.rrd.digest``)
    /legsim/file_digest          JSON: the SHA-256 of the file's bytes before it (files only)
    /summary                     the run summary as markdown

A part whose shape is not a moved, rotated or stretched copy of its first shape in some sample
(or is absent there) is drawn from that sample on by its own polyline in world coordinates
under an identity transform; its first shape is then logged at its first sample instead of
statically.
"""

FORMAT = "legsim-rrd-2"
#: Formats of earlier versions, which this version refuses by name.
OLD_FORMATS = ("legsim-rrd-1",)
APPLICATION_ID = "legsim"
TIMELINE = "sim_time"
SAMPLE_TIMELINE = "sample"

WORLD = "/world"
ROBOT = "/world/robot"
SCENERY = "/world/scenery"
STATE = "/state"
MODE = "/mode"
STRIP = "/strip"
TRANSITIONS = "/events/transitions"
STRIPS = "/events/strips"
WARNINGS = "/events/warnings"
SAMPLES = "/legsim/samples"
META = "/legsim/meta"
DIGEST = "/legsim/digest"
FILE_DIGEST = "/legsim/file_digest"
SUMMARY = "/summary"

# Colours (RGB) of robot parts and modes in the viewer, in order; scenery is grey.
PALETTE = [
    (31, 119, 180),
    (214, 39, 40),
    (44, 160, 44),
    (255, 127, 14),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (23, 190, 207),
    (188, 189, 34),
]
SCENERY_COLOUR = (110, 110, 110)

#: What the coordinates of a unit are called in the names of the plot views, in the order the
#: views are laid out; other units are named by the unit alone.
UNIT_WORDS = {
    "m": "positions",
    "rad": "angles",
    "m/s": "velocities",
    "rad/s": "angular velocities",
    "m/s^2": "accelerations",
    "rad/s^2": "angular accelerations",
    "N": "forces",
    "N m": "torques",
    "J": "energies",
    "s": "times",
}
NO_UNIT = "without unit"


def entity(parent: str, name: str) -> str:
    """The entity path of ``name`` (a coordinate or a part, any text) under ``parent``."""
    import rerun as rr

    return f"{parent}/{rr.escape_entity_path_part(name)}"
