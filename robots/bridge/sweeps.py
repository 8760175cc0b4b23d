"""Where placed points go between two checked points of a run, on the cubics of their
coordinates through their values and velocities at both (the step's interpolant, to O(dt^4)):
the range each point sweeps, which rules a stretch clear of the ground (``Watch.clear``), and
the times its x turns onto another piece of the terrain and back (``Watch.probe``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from legsim.relaxed.between import cubic_least
from legsim.terrain import pieces_along

from .placements import Placements


def cubic_range(
    v0: np.ndarray, v1: np.ndarray, r0: np.ndarray, r1: np.ndarray, dt: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The least and the most of the cubic through (0, v0) and (dt, v1) with slopes r0, r1 over
    [0, dt], arrays of one shape: its ends' or its interior extremes (``cubic_least``)."""
    least = np.fmin(np.minimum(v0, v1), cubic_least(v0, v1, r0, r1, dt)[1])
    most = np.fmax(np.maximum(v0, v1), -cubic_least(-v0, -v1, -r0, -r1, dt)[1])
    return least, most


def swept(
    placements: Placements, columns: Any, ta: np.ndarray, xa: np.ndarray, tb: np.ndarray, xb: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where each placed point (``columns`` of ``placements``) goes between two checked points at
    times ta, tb (J,) and states xa, xb (J, >= 2 n): its least and most x and its least height
    (m), (J, points) each."""
    states = np.concatenate([xa, xb])
    a, b = np.split(placements.at(states)[:, columns], 2)
    va, vb = np.split(placements.velocities(states)[:, columns], 2)
    dt = (tb - ta)[:, None]
    x_low, x_high = cubic_range(a[..., 0], b[..., 0], va[..., 0], vb[..., 0], dt)
    z_low, _ = cubic_range(a[..., 1], b[..., 1], va[..., 1], vb[..., 1], dt)
    return x_low, x_high, z_low


def placed_turns(
    placements: Placements, columns: Any, terrain: np.ndarray, t: np.ndarray, states: np.ndarray
) -> np.ndarray:
    """``turns_onto_other_pieces`` of the placed points ``columns`` of ``placements`` between
    neighbouring checked points at times t (N,) and states (N, >= 2 n), on the ``terrain``
    encoded as an array: (N - 1, points, 2)."""
    x, vx = placements.at(states)[:, columns, 0], placements.velocities(states)[:, columns, 0]
    return turns_onto_other_pieces(terrain, t, x, vx)


def turns_onto_other_pieces(terrain: np.ndarray, t: np.ndarray, x: np.ndarray, vx: np.ndarray) -> np.ndarray:
    """(N - 1, P, 2): between each two neighbouring checked points at times t (N,) (s), where
    points are at x (N, P) (m) moving at vx (N, P) (m/s), the times at which a point's x turns
    (where its cubic is least, then where it is most) on another piece of the ``terrain``
    (``legsim.terrain.pieces_along``) than the one it starts on: past a profile's corner, which
    it may cross back before the next checked point; nan where it does not turn there."""
    out = np.full((t.shape[0] - 1, x.shape[1], 2), np.nan)
    x0, x1, v0, v1 = x[:-1], x[1:], vx[:-1], vx[1:]
    dt = np.broadcast_to(np.diff(t)[:, None], x0.shape)
    # The cubic stays within its ends' range widened by (4/27) dt (|v0| + |v1|), the most of the
    # Hermite basis's velocity terms: only where that reaches another piece can it turn onto one.
    reach = (4.0 / 27.0) * dt * (np.abs(v0) + np.abs(v1))
    start, low, high = pieces_along(terrain, np.stack([x0, np.minimum(x0, x1) - reach, np.maximum(x0, x1) + reach]))
    j, p = np.nonzero((low != start) | (high != start))
    if j.size == 0:
        return out
    ends, rates, span = (x0[j, p], x1[j, p]), (v0[j, p], v1[j, p]), dt[j, p]
    for column, sign in enumerate((1.0, -1.0)):  # where x is least, then where it is most
        s, extreme = cubic_least(sign * ends[0], sign * ends[1], sign * rates[0], sign * rates[1], span)
        turns = ~np.isnan(s)
        other = turns & (pieces_along(terrain, np.where(turns, sign * extreme, ends[0])) != start[j, p])
        out[j[other], p[other], column] = t[j[other]] + s[other] * span[other]
    return out
