"""Positions and velocities of many frames at many stored states in one compiled call of the
native library, for checks that scan a whole run (a link passing below the ground). A leaf module: the stamp of
its compiled code covers only this file and what it imports.
"""

from __future__ import annotations

import numpy as np
from legsim.robots._native.calls import lsn_frames

from legsim.compiled.functions import model_function

_F8 = 8  # bytes per float64, for pointer offsets


@model_function
def frame_motions(handle: int, states: np.ndarray, n: int, frames: np.ndarray, out: np.ndarray) -> None:
    """The world (x, z) (m) and velocity (vx, vz) (m/s) of each frame at each state into out
    (rows, count, 4).

    handle: the native model; states (rows, >= 2 n): each row's configuration q = row[:n] and
    velocity row[n:2n], C-contiguous; frames (count,): the frame ids as float64."""
    count = frames.shape[0]
    kin = np.empty(4 * count)
    for k in range(states.shape[0]):
        row = states[k]
        address = row.ctypes.data
        lsn_frames(handle, address, address + _F8 * n, count, frames.ctypes.data, kin.ctypes.data)
        for i in range(count):
            for j in range(4):
                out[k, i, j] = kin[4 * i + j]
