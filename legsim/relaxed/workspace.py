"""The arrays one run's loop works in (``Workspace``), allocated once and grown by the driver.

Every array is named by ``layout``: settings (``cf``, ``ci``), the run's state and counters (``fs``,
``iv``), the current point and the step's scratch, the guards, the controller's input (and the input
previewed after a crossing, ``u_after``, and the input of an outcome kept in reserve, ``u_kept``)
and memory, the Zeno histories, and the output buffers the driver drains into the execution:
points (T, X, DX), visits, and crossing records (``rec_f``, ``rec_i``, q in ``rec_q``, the image
in ``rec_x``); for a linearly implicit method the Jacobian J, the factors LU of I - gamma h J,
their row pivots and df/dt (ft). Widths: W the longest state of the run's modes (memory
included), G the most guards, S the method's stages and extra stages, U the input's entries, M
the memory's.
"""

from __future__ import annotations

import functools
import math
from collections import namedtuple
from collections.abc import Mapping
from types import MappingProxyType

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
    "cf ci fs iv x K XS x1 k1 q w g_here g1 g_w crossed u u_after u_kept m_new history T X DX visits rec_f rec_i "
    "rec_q rec_x J LU piv ft",
)

#: Capacity of the output buffers at most: points (about 2 MB at W = 16), crossing records and
#: visits. They start at ``FIRST_SHARE`` of that and grow by ``GROWTH`` each time they fill: a
#: short run (a few hundred steps) would spend more time mapping and faulting in 2 MB of zeros
#: (about 0.3 ms) than stepping, while a long one drains full buffers into its execution anyway.
POINTS, RECORDS, VISITS = 8192, 1024, 1024
FIRST_SHARE, GROWTH = 16, 4
#: The output buffers of the points: the largest arrays, and the only ones ``cleared`` leaves as
#: they are (a run reads no row of them it has not written).
POINT_BUFFERS = frozenset({"T", "X", "DX"})
#: Guards and history rows a workspace has room for at least: a run that reaches a mode with more
#: guards or transitions resizes the workspace (a few microseconds per array), while this room
#: costs a few hundred bytes.
LEAST_GUARDS, LEAST_HISTORIES = 8, 32


# Kept by their arguments: a short run's whole Python setup is tens of microseconds, and
# building this table took about 9 of them; the few sizes a program's runs take repeat.
@functools.lru_cache(maxsize=256)
def shapes(
    width: int, guards: int, stages: int, inputs: int, memory: int, histories: int, share: int = 0
) -> Mapping[str, tuple]:
    """Each array's (shape, dtype) for states of up to ``width`` entries, ``guards`` guards,
    ``stages`` stage rows, an input of ``inputs`` entries, ``memory`` memory values and
    ``histories`` history rows; output buffers of 1/``share`` of their largest capacity (0: of
    ``FIRST_SHARE``). Read-only: the same table is handed to every caller with these sizes."""
    W, G, S = max(1, width), max(LEAST_GUARDS, guards), max(1, stages)
    H = max(LEAST_HISTORIES, histories)
    points, records, visits = _capacities(share or FIRST_SHARE)
    f, i = np.float64, np.int64
    return MappingProxyType(
        {
            "cf": ((FLOAT_SETTINGS,), f),
            "ci": ((INT_SETTINGS,), i),
            "fs": ((FLOAT_STATE,), f),
            "iv": ((INT_STATE,), i),
            **{name: ((W,), f) for name in ("x", "XS", "x1", "k1", "q", "w", "ft")},
            "K": ((S, W), f),
            **{name: ((G,), f) for name in ("g_here", "g1", "g_w", "crossed")},
            "u": ((inputs,), f),
            "u_after": ((inputs,), f),
            "u_kept": ((inputs,), f),
            "m_new": ((memory,), f),
            "history": ((H, HISTORY_FIELDS), f),
            "T": ((points,), f),
            "X": ((points, W), f),
            "DX": ((points, W), f),
            "visits": ((visits, VISIT_FIELDS), i),
            "rec_f": ((records, RECORD_FLOATS), f),
            "rec_i": ((records, RECORD_INTS), i),
            "rec_q": ((records, W), f),
            "rec_x": ((records, W), f),
            "J": ((W, W), f),
            "LU": ((W, W), f),
            "piv": ((W,), i),
        }
    )


def allocate(width: int, guards: int, stages: int, inputs: int, memory: int, histories: int) -> Workspace:
    """A workspace for states of up to ``width`` entries, ``guards`` guards, ``stages`` stage
    rows, an input of ``inputs`` entries, ``memory`` memory values and ``histories`` rows.

    Its arrays but the point buffers are views of one float64 and one int64 block, so that
    ``cleared`` readies it for another run in two writes."""
    arrays = shapes(width, guards, stages, inputs, memory, histories)
    carved = {name: np.zeros(shape, dtype) for name, (shape, dtype) in arrays.items() if name in POINT_BUFFERS}
    for dtype in (np.float64, np.int64):
        rest = {name: shape for name, (shape, kind) in arrays.items() if kind is dtype and name not in carved}
        block = np.zeros(sum(math.prod(shape) for shape in rest.values()), dtype)
        start = 0
        for name, shape in rest.items():
            size = math.prod(shape)
            carved[name] = block[start : start + size].reshape(shape)
            start += size
    ws = Workspace(**carved)
    ws.iv[I_JACOBIAN_AGE] = -1
    return ws


def cleared(ws: Workspace) -> Workspace:
    """``ws`` (as ``allocate`` made it) ready for a new run, as ``allocate`` leaves a workspace:
    every array zero but the point buffers, whose rows a run writes before it reads them."""
    ws.cf.base.fill(0.0)
    ws.ci.base.fill(0)
    ws.iv[I_JACOBIAN_AGE] = -1
    return ws


def _capacities(share: int) -> tuple[int, int, int]:
    """(points, records, visits) the output buffers hold at 1/share of their largest capacity."""
    return POINTS // share, RECORDS // share, VISITS // share


def _share(ws: Workspace) -> int:
    return POINTS // ws.T.shape[0]


def resized(ws: Workspace, width: int, guards: int, inputs: int, histories: int) -> Workspace:
    """``ws`` with room for wider states, more guards, inputs or history rows (its contents
    kept), or ``ws`` itself when it has room. Only the arrays whose shape grows are new: the
    output buffers, the largest, stay as they are unless the state widens."""
    W, G = ws.x.shape[0], ws.g1.shape[0]
    H, U = ws.history.shape[0], ws.u.shape[0]
    if width <= W and guards <= G and histories <= H and inputs <= U:
        return ws
    sizes = (max(width, W), max(guards, G), ws.K.shape[0], max(inputs, U), ws.m_new.shape[0], max(histories, 2 * H))
    return _regrown(ws, shapes(*sizes, share=_share(ws)))


def with_longer_buffers(ws: Workspace) -> Workspace:
    """``ws`` with output buffers ``GROWTH`` times longer (their rows in use kept), or ``ws``
    itself when they are as long as they get."""
    share = _share(ws)
    if share <= 1:
        return ws
    W, G, S = ws.x.shape[0], ws.g1.shape[0], ws.K.shape[0]
    sizes = (W, G, S, ws.u.shape[0], ws.m_new.shape[0], ws.history.shape[0])
    return _regrown(ws, shapes(*sizes, share=max(1, share // GROWTH)))


def _regrown(ws: Workspace, arrays: Mapping[str, tuple]) -> Workspace:
    """``ws`` with the arrays whose shape differs from ``arrays``' made anew, their contents (the
    output buffers' rows in use) copied."""
    used = _used_rows(ws)
    grown = {}
    for name, (shape, dtype) in arrays.items():
        old = getattr(ws, name)
        if old.shape == shape:
            continue
        new = np.zeros(shape, dtype)
        rows = used.get(name, old.shape[0])
        new[(slice(0, rows), *(slice(0, k) for k in old.shape[1:]))] = old[:rows]
        grown[name] = new
    return ws._replace(**grown)


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
