"""The relaxed hybrid quotient-space metric (paper 000, Section III) and distances between executions.

Paper 000 glues the domains of a hybrid system into one metric space: a point on a guard and its
reset image are the same point (Definition 12, the hybrid quotient space M), and with the
relaxation every guard is thickened into a strip of width eps whose transverse coordinate tau
runs from 0 (the guard) to eps (where the reset is applied) (Definitions 14, 15, 19; M^eps).
The distance is the length of the shortest *connected* curve (Definition 5): straight pieces
inside the domains, joined where a guard point p is identified with its reset image R(p), each
identification in M^eps paid for by crossing its strip, a length eps (the strip metric (12) is
d_G + |tau - tau'|, so moving along the guard inside the strip never beats moving in the domain).

``distance(system, a, b, eps)`` computes

    min( |x_a - x_b|                              (same mode only),
         min over edge walks e_1..e_m (m <= max_hops), over guard points p_i:
             |x_a - in_1(p_1)| + sum |out_i(p_i) - in_{i+1}(p_{i+1})| + |out_m(p_m) - x_b| + m eps )

where a walk may cross a transition either way (the quotient is symmetric): forwards
``in(p) = p, out(p) = R(p)``, backwards ``in(p) = R(p), out(p) = p``. eps = 0 gives the
unrelaxed distance on M; d_0 <= d_eps <= d_0 + k eps with k the crossings of a shortest path
(Theorem 21).

Units: the strip width eps is in guard units (paper: the transverse coordinate), added to
Euclidean lengths of states; both are the paper's choice.

The package, from the declarations a model uses up to the comparison of executions:

* ``shapes``: ``CoordinateGuard`` and ``AffineReset``, guards and resets of known shape.
* ``detect``: recognising those shapes in plain model functions by probing.
* ``geometry``: guard sets cut into pieces, reset models, the transition graph (cached per system).
* ``projection``: distances from a point to a guard piece or its reset image, and their bounds.
* ``solvers``: SLSQP, golden section, and the log-barrier method for sums of norms.
* ``walk``: the shortest path through one sequence of crossings.
* ``search``: the search over walks; ``distance``, ``shortest_path``, ``MetricPath``, ``Crossing``.
* ``executions``: ``distances``, ``rho``, ``position_error``, ``trajectory_space_distance``.
* ``inputs``: argument checks and ``MetricError``.
"""

from .executions import distances, position_error, rho, trajectory_space_distance
from .geometry import geometry_of
from .inputs import MetricError
from .search import Crossing, MetricPath, distance, shortest_path
from .shapes import AffineReset, CoordinateGuard

#: ``geometry_of`` under the private name code outside the package imports it by.
_geometry = geometry_of

__all__ = [
    "AffineReset",
    "CoordinateGuard",
    "Crossing",
    "MetricError",
    "MetricPath",
    "distance",
    "distances",
    "position_error",
    "rho",
    "shortest_path",
    "trajectory_space_distance",
]
