"""The native library's functions as numba sees them: external symbols resolved by name once
``legsim.robots._native.load()`` has loaded the library (call it before compiling or loading any
function that calls these). Pointers are ``array.ctypes.data`` of contiguous float64 arrays;
the model handle comes from ``legsim.robots._native.create_model``. Signatures and units: pinlegsim.cpp.

Each is also callable from Python (through ctypes, with the same arguments), so that a model
function calling them runs as plain Python too (``simulate(python=True)`` runs their sources).
"""

from __future__ import annotations

import ctypes
from typing import Any

from numba import types
from numba.core.datamodel import models, register_default

_h, _p = types.int64, types.voidptr
_CTYPES = {types.int64: ctypes.c_long, types.voidptr: ctypes.c_void_p, types.float64: ctypes.c_double}


class NativeFunction(types.ExternalFunction):
    """An external function of the native library: compiled code calls it by its symbol, Python
    through ctypes."""

    def __call__(self, *args: Any) -> Any:
        from . import library

        fn = getattr(library(), self.symbol)
        fn.restype = None
        fn.argtypes = [_CTYPES[a] for a in self.sig.args]
        fn(*(int(a) if t is not types.float64 else float(a) for a, t in zip(args, self.sig.args, strict=True)))


# Compiled code holds it as numba holds its external functions.
register_default(NativeFunction)(models.OpaqueModel)

#: lsn_aba(h, q, v, tau, a_out): unconstrained acceleration (nv,).
lsn_aba = NativeFunction("lsn_aba", types.void(_h, _p, _p, _p, _p))
#: lsn_frames(h, q, v, count, frames, out): (x, z, vx, vz) of each frame, out (4 count,).
lsn_frames = NativeFunction("lsn_frames", types.void(_h, _p, _p, types.int64, _p, _p))
#: lsn_frame_jacobian(h, q, frame, out): (x, z, J row x (nv), J row z (nv)) of a frame at q.
lsn_frame_jacobian = NativeFunction("lsn_frame_jacobian", types.void(_h, _p, types.int64, _p))
#: lsn_constrained(h, q, v, tau, count, rigid, slopes, a_out, lam_out): KKT dynamics of rigid
#: blocks; slopes: the terrain's (dh/dx, d2h/dx2) under each block (zeros: level ground, rows x, z).
lsn_constrained = NativeFunction("lsn_constrained", types.void(_h, _p, _p, _p, types.int64, _p, _p, _p, _p))
#: lsn_impact(h, q, v, count, rigid, slopes, coeff, v_out, impulse_out): generalised Newton
#: impact, and its impulses (one per row) unless impulse_out is 0; slopes as for lsn_constrained.
lsn_impact = NativeFunction("lsn_impact", types.void(_h, _p, _p, types.int64, _p, _p, _p, _p, _p))
#: lsn_momentum_about(h, q, v, frame, out): (angular momentum about the frame's origin along y,
#: the frame's x, z) at (q, v).
lsn_momentum_about = NativeFunction("lsn_momentum_about", types.void(_h, _p, _p, types.int64, _p))
#: lsn_crba(h, q, out): the joint-space inertia matrix M (nv, nv), row-major.
lsn_crba = NativeFunction("lsn_crba", types.void(_h, _p, _p))
#: lsn_gravity(h, q, out): the generalised gravity g(q) (nv,).
lsn_gravity = NativeFunction("lsn_gravity", types.void(_h, _p, _p))
#: lsn_frame_motion(h, q, v, a, frame, out): a frame's (vx, vz, ax, az) at (q, v, a), out (4,).
lsn_frame_motion = NativeFunction("lsn_frame_motion", types.void(_h, _p, _p, _p, types.int64, _p))
#: lsn_minverse(h, q, out): the inverse inertia matrix M^-1 (nv, nv), row-major.
lsn_minverse = NativeFunction("lsn_minverse", types.void(_h, _p, _p))
#: lsn_solve(m, A, b, least_norm, n, MWt, count, cones, out): A y = b (A (m, m) row-major) into
#: out[:m], out[m] = 1.0 where solved, 0.0 where not; a singular A takes the least-norm y where
#: that is unique in its motion (least_norm: A symmetric; else MWt (n, m) = M^-1 W^T, row-major),
#: shared by the capacities of the count cones (tangent row or -1, normal row, mu).
lsn_solve = NativeFunction(
    "lsn_solve", types.void(types.int64, _p, _p, types.int64, types.int64, _p, types.int64, _p, _p)
)
#: lsn_round_moving(h, frame): make a round frame moving: its offset is set per configuration.
lsn_round_moving = NativeFunction("lsn_round_moving", types.void(_h, types.int64))
#: lsn_round_place(h, q, frame, dx, dz): a moving round frame's offset -r n (m) at q.
lsn_round_place = NativeFunction("lsn_round_place", types.void(_h, _p, types.int64, types.float64, types.float64))
#: lsn_tally(h, slot, amount): add amount to the robot's counter slot.
lsn_tally = NativeFunction("lsn_tally", types.void(_h, types.int64, types.float64))
