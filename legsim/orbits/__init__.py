"""Periodic orbits of hybrid systems: Poincare sections, return maps, fixed points, Floquet
multipliers and continuation.

A gait is a periodic orbit of a hybrid system. We find one as a fixed point of the *return
map* P of a Poincare section S: start on S, simulate with the relaxed integrator until the
trajectory comes back to S, and ask that P(x) = x.

Modules, in the order a computation uses them:

* ``sections``: ``Section`` (a level set crossed in a direction, or the states just after a
  transition) and its binding to a system.
* ``problem``: ``OrbitProblem``, the system, section, integrator settings and unknowns.
* ``returns``: the return map (``ReturnMap``, ``return_map``, ``Return``): where the trajectory
  comes back to the section, and the period without the strips' holds.
* ``jacobians``: the return map's Jacobian by saltation matrices or finite differences, and the
  Floquet multipliers.
* ``kinks``: whether a finite-difference Jacobian's columns are derivatives at all (forward and
  backward differences that agree); a return map with a kink at the orbit gets no stability
  verdict.
* ``newton``: ``find_orbit`` (Gauss-Newton on the orbit equations) and ``OrbitResult``.
* ``continuation``: ``continue_family`` and the stability changes along a family.

A scene's ``[orbit]`` section is read by ``legsim.scene.orbit`` (``problem_from_scene``), on the
scene layer above this one.
"""

from __future__ import annotations

from .continuation import Family, FamilyPoint, StabilityChange, continue_family
from .errors import OrbitError
from .jacobians import (
    MAX_FD_STEP,
    default_fd_step,
    floquet_multipliers,
    jacobian_fd,
    jacobian_fd_checked,
    jacobian_saltation,
    reset_on_guard_jacobian,
    saltation_matrix,
)
from .kinks import CheckedJacobian
from .newton import find_orbit
from .problem import MAX_STEPS_PER_RETURN, OrbitProblem, Return
from .result import STATUSES, OrbitResult
from .returns import ReturnMap, return_map
from .sections import Section

__all__ = [
    "MAX_FD_STEP",
    "MAX_STEPS_PER_RETURN",
    "STATUSES",
    "CheckedJacobian",
    "Family",
    "FamilyPoint",
    "OrbitError",
    "OrbitProblem",
    "OrbitResult",
    "Return",
    "ReturnMap",
    "Section",
    "StabilityChange",
    "continue_family",
    "default_fd_step",
    "find_orbit",
    "floquet_multipliers",
    "jacobian_fd",
    "jacobian_fd_checked",
    "jacobian_saltation",
    "reset_on_guard_jacobian",
    "return_map",
    "saltation_matrix",
]
