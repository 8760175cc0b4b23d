"""The variational equation along a stored segment, compiled: the saltation Jacobian's inner loop
run by numba on a mode's compiled twin.

``jacobians._segment_sensitivity`` multiplies, step by step, the derivative of each Runge-Kutta
step of a segment (the variational equation stepped by the same tableau on the same steps). On
the Python path every stage costs a field and a field Jacobian through Python (~100 us a step
on the compass gait, 85% of an orbit search). When the segment's mode has a compiled twin
(``legsim.compiled.CompiledMode``) and the run has no control, this module does the same
product in compiled code, calling the twin's field (~0.6 us) for the stages and for the field
Jacobians by central differences (``legsim.derivatives.CENTRAL_STEP``, each coordinate's step
scaled by max(1, |x_j|): relative error ~1e-10, against the Python path's analytic
``Mode.jacobian`` where a mode has one, or its forward differences, ~1e-8, where it has none).

Like the step loop's kernels (``legsim.compiled.generate``), the compiled functions are written
as plain Python here and copied into a module per twin field, generated once into
``legsim.compiled.cache_dir()`` with the field imported as a module-level global: numba caches
that module's machine code on disk, where passing the field as an argument would compile it
again in every process. A twin whose field is not a module-level function, a segment whose
compiled product is not finite (a perturbed stage past the model's range), or a cache folder
that cannot be written leave the segment to the Python path (``compiled_sensitivity`` returns
None).
"""

from __future__ import annotations

import hashlib
import importlib.util
import inspect
import math
import sys
from typing import Any

import numpy as np

from ..derivatives import CENTRAL_STEP, FORWARD_STEP
from ..errors import OutputError
from ..execution import Segment
from ..hybrid import Mode
from ..methods import Tableau

#: Largest relative change of the field Jacobian over a step (max norms) for which a Newton
#: Jacobian interpolates it between the step's ends: the interpolation's error is then about
#: (change)^2 / 8 of the step's contribution, ~1e-6 over a compass-gait step at h = 2e-3
#: (changes ~4e-3 a step), against ~1e-8 for forward differences at every stage.
INTERPOLATION_LIMIT = 1e-2


def _twin_field(t, x, p):  # bound per twin field in the generated module
    raise NotImplementedError


# -- the compiled functions (plain Python; the generated module jits copies of them) -------------
def _k_field_jacobian(t, x, p, central, J):
    # df/dx by central differences of the twin's field, or forward ones, into J (n, n); the
    # relative steps and their scaling are legsim.derivatives'.
    n = x.shape[0]
    plus = x.copy()
    minus = x.copy()
    f_minus = x if central else _twin_field(t, x, p)
    for j in range(n):
        scale = max(1.0, abs(x[j]))
        plus[j] = x[j] + (CENTRAL_STEP if central else FORWARD_STEP) * scale
        f_plus = _twin_field(t, plus, p)
        if central:
            minus[j] = x[j] - CENTRAL_STEP * scale
            f_minus = _twin_field(t, minus, p)
        width = plus[j] - minus[j]  # the step actually taken, after rounding
        for i in range(n):
            J[i, j] = (f_plus[i] - f_minus[i]) / width
        plus[j] = x[j]
        minus[j] = x[j]


def _k_product(A, B, out):
    # out = A @ B for small square matrices (numba's @ calls BLAS, slower at n ~ 5).
    n = A.shape[0]
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(n):
                acc += A[i, k] * B[k, j]
            out[i, j] = acc


def _k_stage_input(j, h, A, dK, dX):
    # dX = I + h sum_m A_jm dK_m: the derivative of stage j's point.
    n = dX.shape[0]
    for d in range(n):
        for e in range(n):
            dX[d, e] = 1.0 if d == e else 0.0
    for m in range(j):
        w = h * A[j, m]
        if w != 0.0:
            for d in range(n):
                for e in range(n):
                    dX[d, e] += w * dK[m, d, e]


def _k_stages_exact(t0, x0, h, A, c, p, central, K, dK, X, dX, J, out):
    # dK_j = J(t_j, X_j) dX_j with the field Jacobian at each stage point X_j.
    n = x0.shape[0]
    for j in range(c.shape[0]):
        for d in range(n):
            X[d] = x0[d]
        for m in range(j):
            w = h * A[j, m]
            if w != 0.0:
                for d in range(n):
                    X[d] += w * K[m, d]
        _k_stage_input(j, h, A, dK, dX)
        tj = t0 + c[j] * h
        K[j, :] = _twin_field(tj, X, p)
        _k_field_jacobian(tj, X, p, central, J)
        _k_product(J, dX, out)
        dK[j, :, :] = out


def _k_stages_interpolated(h, full, A, c, J0, J1, dK, dX, J, out):
    # dK_j = J(t_j) dX_j with the field Jacobian interpolated linearly in time between the
    # step's stored ends (J0 at its start, J1 a full step of length ``full`` later).
    n = dX.shape[0]
    for j in range(c.shape[0]):
        _k_stage_input(j, h, A, dK, dX)
        theta = c[j] * h / full
        for d in range(n):
            for e in range(n):
                J[d, e] = (1.0 - theta) * J0[d, e] + theta * J1[d, e]
        _k_product(J, dX, out)
        dK[j, :, :] = out


def _k_slowly_varying(J0, J1):
    # Whether the field Jacobian changes over the step by at most INTERPOLATION_LIMIT (max norms).
    change = 0.0
    size = 0.0
    for d in range(J0.shape[0]):
        for e in range(J0.shape[1]):
            change = max(change, abs(J1[d, e] - J0[d, e]))
            size = max(size, abs(J0[d, e]))
    return change <= INTERPOLATION_LIMIT * size


def _k_sensitivity(ts, xs, count, t_stop, A, b, c, p, newton, Phi):
    # Phi <- (derivative of step count-1) ... (derivative of step 0) Phi, each step from its
    # stored start point, the last cut at t_stop (module docstring for ``newton``).
    n = xs.shape[1]
    s = b.shape[0]
    K = np.zeros((s, n))
    dK = np.zeros((s, n, n))
    X, dX, J, S, out = np.empty(n), np.empty((n, n)), np.empty((n, n)), np.empty((n, n)), np.empty((n, n))
    J0, J1 = np.empty((n, n)), np.empty((n, n))
    if newton:
        _k_field_jacobian(ts[0], xs[0].copy(), p, False, J0)
    for i in range(count):
        t0 = ts[i]
        if t0 >= t_stop:
            break
        if newton:
            _k_field_jacobian(ts[i + 1], xs[i + 1].copy(), p, False, J1)
        t1 = min(ts[i + 1], t_stop)
        h = t1 - t0
        if h > 0.0:
            if newton and _k_slowly_varying(J0, J1):
                _k_stages_interpolated(h, ts[i + 1] - t0, A, c, J0, J1, dK, dX, J, out)
            else:
                _k_stages_exact(t0, xs[i], h, A, c, p, not newton, K, dK, X, dX, J, out)
            for d in range(n):
                for e in range(n):
                    acc = 1.0 if d == e else 0.0
                    for j in range(s):
                        acc += h * b[j] * dK[j, d, e]
                    S[d, e] = acc
            _k_product(S, Phi, out)
            Phi[:, :] = out
        if newton:
            J0[:, :] = J1


_COMPILED = (
    _k_field_jacobian,
    _k_product,
    _k_stage_input,
    _k_stages_exact,
    _k_stages_interpolated,
    _k_slowly_varying,
    _k_sensitivity,
)
_MODULES: dict[int, Any] = {}  # by id of the twin's field: the generated module, or None


def compiled_sensitivity(
    mode: Mode, tableau: Tableau, seg: Segment, t_stop: float | None = None, newton: bool = False
) -> np.ndarray | None:
    """d x(end) / d x(start) along ``seg`` (a segment of ``mode``; the last step cut at
    ``t_stop``, s), shape (n, n), computed by the mode's compiled twin: to ~1e-10 relative, or
    with ``newton`` to the ~1e-6 a Newton step needs at a quarter of the cost (module
    docstring); None when the mode has no usable twin or the product is not finite (the caller
    then takes the Python path)."""
    twin = mode.compiled
    if twin is None:
        return None
    if twin.controls is not None:  # a run without control: the twin's record says so
        twin.controls(None)(twin.params)
    module = _module_for(twin.field)
    if module is None:
        return None
    n = seg.x.shape[1]
    Phi = np.eye(n)
    stop = math.inf if t_stop is None else float(t_stop)
    module._k_sensitivity(
        np.ascontiguousarray(seg.t, dtype=float),
        np.ascontiguousarray(seg.x, dtype=float),
        len(seg.t) - 1,
        stop,
        np.ascontiguousarray(tableau.A, dtype=float),
        np.ascontiguousarray(tableau.b, dtype=float),
        np.ascontiguousarray(tableau.c, dtype=float),
        twin.params,
        bool(newton),
        Phi,
    )
    return Phi if np.all(np.isfinite(Phi)) else None


def _module_for(field: Any) -> Any:
    key = id(field)
    if key not in _MODULES:
        _MODULES[key] = _generate(field)
    return _MODULES[key]


def module_source(field_name: str) -> str:
    """The generated module's text for a twin field ``module:qualname``."""
    module, qualname = field_name.split(":")
    lines = [
        "# Generated by legsim.orbits.variational; edit that module, not this file.",
        "import math",
        "",
        "import numba",
        "import numpy as np",
        "",
        f"from {module} import {qualname} as _twin_field",
        "",
        f"CENTRAL_STEP = {CENTRAL_STEP!r}",
        f"FORWARD_STEP = {FORWARD_STEP!r}",
        f"INTERPOLATION_LIMIT = {INTERPOLATION_LIMIT!r}",
        "_njit = numba.njit(cache=True, fastmath=False, nogil=True)",
    ]
    for fn in _COMPILED:
        lines += ["", "", "@_njit", inspect.getsource(fn).rstrip()]
    return "\n".join(lines) + "\n"


def _generate(field: Any) -> Any:
    """The generated module for a twin field, written to the kernel cache folder once (its name
    a digest of its text, numba's version and the twin's sources, so a changed twin gets a new
    one); None for a field that is not a module-level function or without a writable folder."""
    import numba

    from ..compiled.generate import _twin_sources, cache_dir, importable
    from ..output.files import write_atomic

    name = importable(field)
    if name is None:
        return None
    text = module_source(name)
    digest = hashlib.sha256((text + numba.__version__ + _twin_sources((name,))).encode()).hexdigest()[:20]
    path = cache_dir() / f"legsim_sensitivity_{digest}.py"
    try:
        if not path.exists() or path.read_text() != text:
            write_atomic(path, lambda tmp: tmp.write_text(text), what="compiled sensitivity module", suffixes=(".py",))
        spec = importlib.util.spec_from_file_location(path.stem, path)
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module  # numba's cache finds a function's module by name
        spec.loader.exec_module(module)
        return module
    except (OSError, OutputError):
        return None
