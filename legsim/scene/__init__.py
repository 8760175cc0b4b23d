"""Scene files: a TOML description of one simulation, validated completely before anything runs.

* ``files``: finding scenes by name (``LEGSIM_SCENE_PATH``, then the bundled scenes), reading
  TOML, ``key.path=value`` overrides.
* ``load``: the core sections (``[scene]``, ``[robot]``, ``[effects]``, ``[initial]``,
  ``[integrator]``, ``[output]``) into a ``Scene`` with its model built.
* ``fields``: the error helpers every section's reader shares.

Tool sections (``[orbit]``, ``[certify]``, ``[stochastic]``, ...) are read here too, by the
modules of this package named after them, into the plain arguments their algorithms take:

* ``orbit``: ``[orbit]`` into an ``OrbitProblem``, solver settings and guess (``problem_from_scene``).
* ``certify``: ``[certify]`` into the arguments of ``legsim.certify.certify`` (``certify_scene``).
* ``stochastic``: ``[stochastic]`` into those of ``legsim.stochastic.sample_ensemble``
  (``ensemble_from_scene``).
* ``error_bounds``: the keys and checks ``[certify]`` and ``[stochastic]`` share.

They are imported by name (``from legsim.scene.orbit import problem_from_scene``), not here, so
that loading a scene does not load every tool.
"""

from ..output.summary import run_summary
from .files import (
    SCENE_PATH_ENV,
    apply_overrides,
    bundled_dir,
    parse_override,
    read_toml,
    resolve_scene_path,
    scene_files,
    scene_info,
    search_dirs,
)
from .integrator import MAX_STEPS
from .load import ALLOWED_SECTIONS, CORE_SECTIONS, INITIAL_CHECK, TOOL_SECTIONS, Scene, load_scene

__all__ = [
    "ALLOWED_SECTIONS",
    "CORE_SECTIONS",
    "INITIAL_CHECK",
    "MAX_STEPS",
    "SCENE_PATH_ENV",
    "TOOL_SECTIONS",
    "Scene",
    "apply_overrides",
    "bundled_dir",
    "load_scene",
    "parse_override",
    "read_toml",
    "resolve_scene_path",
    "run_summary",
    "scene_files",
    "scene_info",
    "search_dirs",
]
