"""The arrays one run's loop works in (``Workspace``), allocated once and grown by the driver.

Every array is named by ``layout``: settings (``cf``, ``ci``), the run's state and counters (``fs``,
``iv``), the current point and the step's scratch, the guards, the controller's input (and the input
previewed after a crossing, ``u_after``) and memory, the Zeno histories, and the output buffers the
driver drains into the execution: points (T, X, DX), visits, and crossing records (``rec_f``,
``rec_i``, q in ``rec_q``, the image in ``rec_x``); for a linearly implicit method the Jacobian J,
the factors LU of I - gamma h J, their row pivots and df/dt (ft). Widths: W the longest state of the
run's modes (memory included), G the most guards, S the method's stages and extra stages, U the
input's entries, M the memory's.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from .layout import (
    FLOAT_SETTINGS,
    FLOAT_STATE,
    HISTORY_FIELDS,
    I_JACOBIAN_AGE,
    I_POINTS,
    I_RECORDS,
    I_VISITS,
    INT_SETTINGS,
    INT_STATE,
    RECORD_FLOATS,
    RECORD_INTS,
    VISIT_FIELDS,
)

Workspace = namedtuple(
    "Workspace",
    "cf ci fs iv x K XS x1 k1 q w g_here g1 g_w crossed u u_after m_new history T X DX visits rec_f rec_i rec_q rec_x "
    "J LU piv ft",
)

#: Capacity of the output buffers: points (about 2 MB at W = 16), crossing records and visits.
POINTS, RECORDS, VISITS = 8192, 1024, 1024


def allocate(width: int, guards: int, stages: int, inputs: int, memory: int, histories: int) -> Workspace:
    """A workspace for states of up to ``width`` entries, ``guards`` guards, ``stages`` stage
    rows, an input of ``inputs`` entries, ``memory`` memory values and ``histories`` rows."""
    W, G = max(1, width), max(1, guards)
    ws = Workspace(
        np.zeros(FLOAT_SETTINGS),
        np.zeros(INT_SETTINGS, dtype=np.int64),
        np.zeros(FLOAT_STATE),
        np.zeros(INT_STATE, dtype=np.int64),
        np.zeros(W),
        np.zeros((max(1, stages), W)),
        np.zeros(W),
        np.zeros(W),
        np.zeros(W),
        np.zeros(W),
        np.zeros(W),
        np.zeros(G),
        np.zeros(G),
        np.zeros(G),
        np.zeros(G),
        np.zeros(inputs),
        np.zeros(inputs),
        np.zeros(memory),
        np.zeros((max(1, histories), HISTORY_FIELDS)),
        np.zeros(POINTS),
        np.zeros((POINTS, W)),
        np.zeros((POINTS, W)),
        np.zeros((VISITS, VISIT_FIELDS), dtype=np.int64),
        np.zeros((RECORDS, RECORD_FLOATS)),
        np.zeros((RECORDS, RECORD_INTS), dtype=np.int64),
        np.zeros((RECORDS, W)),
        np.zeros((RECORDS, W)),
        np.zeros((W, W)),
        np.zeros((W, W)),
        np.zeros(W, dtype=np.int64),
        np.zeros(W),
    )
    ws.iv[I_JACOBIAN_AGE] = -1
    return ws


def resized(ws: Workspace, width: int, guards: int, inputs: int, histories: int) -> Workspace:
    """``ws`` with room for wider states, more guards, inputs or history rows (its contents
    kept), or ``ws`` itself when it has room."""
    W, G = ws.x.shape[0], ws.g1.shape[0]
    H, U = ws.history.shape[0], ws.u.shape[0]
    if width <= W and guards <= G and histories <= H and inputs <= U:
        return ws
    bigger = allocate(
        max(width, W), max(guards, G), ws.K.shape[0], max(inputs, U), ws.m_new.shape[0], max(histories, 2 * H)
    )
    used = _used_rows(ws)
    for name in Workspace._fields:
        old, new = getattr(ws, name), getattr(bigger, name)
        rows = used.get(name, old.shape[0])
        new[(slice(0, rows), *(slice(0, k) for k in old.shape[1:]))] = old[:rows]
    return bigger


def _used_rows(ws: Workspace) -> dict[str, int]:
    """The rows of the output buffers that hold data (the rest is never read): a resize copies
    those, not the buffers' whole capacity."""
    points, records, visits = int(ws.iv[I_POINTS]), int(ws.iv[I_RECORDS]), int(ws.iv[I_VISITS])
    return {
        "T": points,
        "X": points,
        "DX": points,
        "visits": visits + 1,
        "rec_f": records,
        "rec_i": records,
        "rec_q": records,
        "rec_x": records,
    }
