"""The native library's functions as numba sees them: external symbols resolved by name once
``legsim._native.load()`` has loaded the library (call it before compiling or loading any
function that calls these). Pointers are ``array.ctypes.data`` of contiguous float64 arrays;
the model handle comes from ``legsim._native.create_model``. Signatures and units: pinlegsim.cpp.
"""

from __future__ import annotations

from numba import types

_h, _p = types.int64, types.voidptr

#: lsn_aba(h, q, v, tau, a_out): unconstrained acceleration (nv,).
lsn_aba = types.ExternalFunction("lsn_aba", types.void(_h, _p, _p, _p, _p))
#: lsn_frames(h, q, v, count, frames, out): (x, z, vx, vz) of each frame, out (4 count,).
lsn_frames = types.ExternalFunction("lsn_frames", types.void(_h, _p, _p, types.int64, _p, _p))
#: lsn_frame_jacobian(h, q, frame, out): (x, z, J row x (nv), J row z (nv)) of a frame at q.
lsn_frame_jacobian = types.ExternalFunction("lsn_frame_jacobian", types.void(_h, _p, types.int64, _p))
#: lsn_constrained(h, q, v, tau, count, rigid, a_out, lam_out): KKT dynamics of rigid blocks.
lsn_constrained = types.ExternalFunction("lsn_constrained", types.void(_h, _p, _p, _p, types.int64, _p, _p, _p))
#: lsn_impact(h, q, v, count, rigid, coeff, v_out, impulse_out): generalised Newton impact, and
#: its impulses (one per row) unless impulse_out is 0.
lsn_impact = types.ExternalFunction("lsn_impact", types.void(_h, _p, _p, types.int64, _p, _p, _p, _p))
#: lsn_momentum_about(h, q, v, frame, out): (angular momentum about the frame's origin along y,
#: the frame's x, z) at (q, v).
lsn_momentum_about = types.ExternalFunction("lsn_momentum_about", types.void(_h, _p, _p, types.int64, _p))
#: lsn_crba(h, q, out): the joint-space inertia matrix M (nv, nv), row-major.
lsn_crba = types.ExternalFunction("lsn_crba", types.void(_h, _p, _p))
#: lsn_gravity(h, q, out): the generalised gravity g(q) (nv,).
lsn_gravity = types.ExternalFunction("lsn_gravity", types.void(_h, _p, _p))
#: lsn_frame_motion(h, q, v, a, frame, out): a frame's (vx, vz, ax, az) at (q, v, a), out (4,).
lsn_frame_motion = types.ExternalFunction("lsn_frame_motion", types.void(_h, _p, _p, _p, types.int64, _p))
#: lsn_minverse(h, q, out): the inverse inertia matrix M^-1 (nv, nv), row-major.
lsn_minverse = types.ExternalFunction("lsn_minverse", types.void(_h, _p, _p))
#: lsn_tally(h, slot, amount): add amount to the robot's counter slot.
lsn_tally = types.ExternalFunction("lsn_tally", types.void(_h, types.int64, types.float64))
