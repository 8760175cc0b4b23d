"""Finding a periodic orbit: Gauss-Newton on the orbit equations, and the result it reports.

The unknowns z are the problem's free coordinates and free parameters; the equations F(z) = 0
are periodicity ``P(x) - x`` on the non-cyclic coordinates other than the section's, s(x) = 0
for a section given as a function, the constraints and the energy level. Each iteration solves
the (possibly overdetermined, consistent) linear system by SVD and halves the step while it
does not reduce the max-norm residual. Where no halving does, a watchdog takes up to
``WATCHDOG_STEPS`` full steps that may raise the residual for a while, and keeps them once one
halves it: at a kink of the return map (an event order switching at the orbit) difference
Jacobians mix the map's pieces, and their first step can raise the residual although the next
ones converge.

Failures are never answers: ``find_orbit`` returns an ``OrbitResult`` whose ``status`` says why
it stopped (``no_return``, ``simulation_failed``, ``singular_jacobian``, ``diverged``,
``stalled``, ``max_iterations``, ``map_unresolved``) with a message; ``result.raise_for_status()``
turns it into an ``OrbitError``.

"Converged" needs more than a residual <= tol: at the first point within tol the search
measures what the return map resolves (``legsim.orbits.accuracy``: its noise under tiny
perturbations, and its change at h/2, eps/2) and reports it as ``map_accuracy``. A residual
within tol but above what the map resolves is refined by further Newton steps (the tolerance
was looser than the map allows); if none lowers it to that level the search ends ``stalled``.
Where the map's noise itself exceeds tol (a jump of the map at the point: no residual below the
noise means anything) the search ends ``map_unresolved``. A tol between the noise and the
resolved level, or a refined map that moves the residual beyond tol, is a warning.

With a controller (``OrbitProblem.controller``) the unknowns gain its memory values after the
free coordinates, the equations ``memory' - memory = 0`` after the periodicity rows, and the
Jacobian is the finite-difference one of the augmented map on (x, memory): the saltation
Jacobian follows the state through each transition, not a controller's memory, which changes
at transitions as a function of the whole stance (a measured stance time), so a search asked for
``jacobian="saltation"`` uses ``"fd"`` and says so in its message.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from ..derivatives import jacobian
from .accuracy import MapAccuracy, estimate_accuracy, refined_problem
from .errors import OrbitError
from .jacobians import check_fd_step, default_fd_step, difference, jacobian_fd, jacobian_fd_checked, jacobian_saltation
from .kinks import CheckedJacobian
from .problem import OrbitProblem, Return
from .result import OrbitResult
from .returns import ReturnMap
from .stability import add_multipliers

#: Relative smallest singular value below which a Newton iteration recomputes the saltation
#: Jacobian accurately before deciding whether it is singular: far above the Newton Jacobian's
#: own error (~1e-6 relative), so that error cannot decide it.
NEAR_SINGULAR = 1e-4
#: Full Newton steps the watchdog (``_NewtonSearch._watchdog``) takes before giving up, how far
#: above the current residual its iterates may go, and the share of it they must end below to be
#: kept (progress, not a residual that rounding or a drift moves in its third digit).
WATCHDOG_STEPS = 4
WATCHDOG_GROWTH = 100.0
WATCHDOG_DECREASE = 0.5


def _step(U: np.ndarray, sv: np.ndarray, Vt: np.ndarray, F: np.ndarray) -> np.ndarray:
    """The Gauss-Newton step -J^+ F from J's SVD (U, singular values sv, V^T)."""
    return -(Vt.T @ ((U.T @ F) / sv))


class _Equations:
    """The orbit equations F(z) = 0 in the unknowns z = (free coordinates, controller memory,
    free parameters)."""

    def __init__(
        self, problem: OrbitProblem, x_template: np.ndarray, memory_template: np.ndarray, rmap: ReturnMap
    ) -> None:
        self.p = problem
        # the state and memory whose fixed values z leaves as they are
        self.template = x_template.copy()
        self.memory_template = np.asarray(memory_template, dtype=float).copy()
        self.rmap = rmap
        self.n_x = len(problem.unknown_idx)
        self.n_xm = self.n_x + len(problem.unknown_memory_idx)

    @property
    def row_names(self) -> list[str]:
        """What each row of F says: the coordinate or memory value asked to return to itself,
        then "section", the constraints' names and "energy"."""
        p = self.p
        names = list(p.names) + list(p.memory_names)
        rows = [names[i] for i in p.augmented_periodic_idx]
        rows += ["section"] * int(p.has_section_row) + [name for name, _ in p.constraints]
        return rows + ["energy"] * int(p.energy is not None)

    def unpack(self, z: np.ndarray) -> tuple[np.ndarray, dict[str, float], np.ndarray]:
        """(state, all parameter values, controller memory) of the unknowns z."""
        x = self.template.copy()
        x[self.p.unknown_idx] = z[: self.n_x]
        memory = self.memory_template.copy()
        memory[self.p.unknown_memory_idx] = z[self.n_x : self.n_xm]
        params = dict(self.p.parameters)
        params.update({name: float(v) for name, v in zip(self.p.free, z[self.n_xm :], strict=True)})
        return x, params, memory

    def pack(self, x: np.ndarray, params: Mapping[str, float], memory: np.ndarray) -> np.ndarray:
        """The unknowns z of a state, parameter values and controller memory."""
        return np.concatenate(
            [x[self.p.unknown_idx], memory[self.p.unknown_memory_idx], [params[name] for name in self.p.free]]
        )

    def extra(self, x: np.ndarray, params: Mapping[str, float]) -> np.ndarray:
        """Rows that do not need a simulation: section function, constraints, energy."""
        p = self.p
        rows = []
        if p.has_section_row:
            rows.append(p.bound.s(x))
        for name, fn in p.constraints:
            try:
                rows.append(float(fn(x, params)))
            except Exception as exc:
                raise OrbitError(
                    f"constraint '{name}' failed at x = {x.tolist()}: {type(exc).__name__}: {exc}"
                ) from exc
        if p.energy is not None:
            system, _ = p.instantiate(params)
            rows.append(float(system.energy(p.bound.mode, x)) - p.energy)  # type: ignore[misc]
        return np.array(rows, dtype=float)

    def residual(self, ret: Return) -> np.ndarray:
        """F at a return's start: periodicity rows (state, then memory), then the extra rows."""
        idx = self.p.augmented_periodic_idx
        return np.concatenate([ret.end[idx] - ret.start[idx], self.extra(ret.x_start, ret.parameters)])

    def evaluate(self, z: np.ndarray) -> tuple[Return, np.ndarray]:
        """(the return from z, F(z)); OrbitError when there is no return."""
        x, params, memory = self.unpack(z)
        ret = self.rmap(x, params, memory)
        return ret, self.residual(ret)

    def jacobian(
        self, z: np.ndarray, ret: Return, method: str, fd_step: float | None, newton: bool = True
    ) -> tuple[np.ndarray, np.ndarray]:
        """(dF/dz, full DP at x): DP by ``method`` ("saltation" or "fd"; the saltation one with
        ``newton`` to the accuracy a Newton step needs, see ``jacobian_saltation``), on (x,
        memory) with a controller; parameter columns by differences of the return map."""
        p = self.p
        x, params, memory = self.unpack(z)
        if method == "saltation":
            DP = jacobian_saltation(p, ret, newton=newton)
        else:
            DP = jacobian_fd(p, x, params, fd_step, columns=p.augmented_unknown_idx, rmap=self.rmap, memory=memory)
        idx = p.augmented_periodic_idx
        cols = []
        for j in p.augmented_unknown_idx:
            col_periodic = DP[idx, j] - (np.array(idx) == j).astype(float)
            extra = self._extra_column(x, params, coord=j) if j < p.dim else np.zeros(p.extra_rows)
            cols.append(np.concatenate([col_periodic, extra]))
        step = default_fd_step(p) if fd_step is None else fd_step
        for name in p.free:

            def shifted(delta: float, name=name) -> np.ndarray:
                q = dict(params)
                q[name] += delta
                return self.residual(self.rmap(x, q, memory))

            d = step * max(1.0, abs(params[name]))
            cols.append(difference(shifted, d, lambda: self.residual(ret), f"parameter {name}"))
        return np.column_stack(cols), DP

    def _extra_column(self, x: np.ndarray, params: Mapping[str, float], coord: int) -> np.ndarray:
        """d(extra rows)/d x[coord] by central differences (the rows are cheap: no simulation)."""
        if not self.p.extra_rows:
            return np.empty(0)

        def along(value: np.ndarray) -> np.ndarray:
            y = x.copy()
            y[coord] = value[0]
            return self.extra(y, params)

        return jacobian(along, x[coord : coord + 1])[:, 0]


def find_orbit(
    problem: OrbitProblem,
    guess: Mapping[str, float] | Sequence[float] | np.ndarray,
    *,
    tol: float = 1e-9,
    max_iterations: int = 30,
    jacobian: str = "saltation",
    fd_step: float | None = None,
    singular_tol: float = 1e-9,
    max_backtracks: int = 8,
    memory: Sequence[float] | np.ndarray | None = None,
) -> OrbitResult:
    """Find a periodic orbit: a fixed point of the return map (P^returns) with Gauss-Newton.

    Parameters
    ----------
    problem: the section, integrator settings, unknowns, fixed coordinates, free parameters.
    guess: initial state of the section's mode (vector or {coordinate: value}); fixed and
        cyclic coordinates keep these values.
    tol: convergence when the max-norm of the equations (state units; J for an energy row)
        is <= tol.
    max_iterations: Newton iterations allowed.
    jacobian: ``"saltation"`` or ``"fd"`` (``legsim.orbits.jacobians``).
    fd_step: relative finite-difference step in (0, 0.1] (default ``default_fd_step(problem)``).
    singular_tol: the Jacobian counts as singular when its smallest singular value is below
        singular_tol times its largest.
    max_backtracks: step halvings tried when a full Newton step does not reduce the residual.
    memory: initial guess of the controller's memory, shape (m,) (default
        ``problem.memory_guess``, a fresh controller's); with a controller the Jacobian is
        always ``"fd"`` (module docstring).

    Returns
    -------
    OrbitResult
        converged or not; never raises for an ordinary failure (see ``STATUSES``).
    """
    if jacobian not in ("saltation", "fd"):
        raise OrbitError(f"jacobian must be 'saltation' or 'fd', got {jacobian!r}")
    if not (isinstance(tol, (int, float)) and tol > 0):
        raise OrbitError(f"tol must be a number > 0, got {tol!r}")
    if isinstance(max_iterations, bool) or not isinstance(max_iterations, int) or max_iterations < 0:
        raise OrbitError(f"max_iterations must be an integer >= 0, got {max_iterations!r}")
    if fd_step is not None:
        fd_step = check_fd_step(fd_step)
    memory0 = _memory_guess(problem, memory)
    fallback = problem.controller is not None and jacobian == "saltation"
    if fallback:
        jacobian = "fd"
    search = _NewtonSearch(
        problem, problem.state_vector(guess), memory0, tol, jacobian, fd_step, singular_tol, max_backtracks
    )
    result = search.run(max_iterations)
    if fallback:
        result.message += "; finite-difference Jacobian: the saltation Jacobian does not follow the controller's memory"
    return result


def _memory_guess(problem: OrbitProblem, memory: Sequence[float] | np.ndarray | None) -> np.ndarray:
    """The memory guess, shape (m,): ``memory`` checked, or the problem's."""
    if memory is None:
        return problem.memory_guess.copy()
    values = np.asarray(memory, dtype=float).reshape(-1)
    if values.shape != (problem.n_memory,) or not np.all(np.isfinite(values)):
        raise OrbitError(
            f"memory guess must be {problem.n_memory} finite number(s) ({list(problem.memory_names)}), "
            f"got {np.asarray(memory).tolist()}",
            key="guess",
        )
    return values


class _NewtonSearch:
    """One Gauss-Newton search: the iterate z, its return and residual, and the history."""

    def __init__(
        self,
        problem: OrbitProblem,
        x0: np.ndarray,
        memory0: np.ndarray,
        tol: float,
        method: str,
        fd_step: float | None,
        singular_tol: float,
        max_backtracks: int,
    ) -> None:
        self.p = problem
        self.tol = tol
        self.method = method
        self.fd_step = fd_step
        self.singular_tol = singular_tol
        self.max_backtracks = max_backtracks
        self.rmap = ReturnMap(problem)
        self.eq = _Equations(problem, x0, memory0, self.rmap)
        self.z = self.eq.pack(x0, problem.parameters, memory0)
        self.history: list[float] = []
        self.ret: Return | None = None
        self.F = np.empty(0)
        self.res = math.inf
        self.accuracy: MapAccuracy | None = None
        self.last_step: np.ndarray | None = None
        #: Newton steps taken, and those of them taken past a kink (``_watchdog``).
        self.iterations = 0
        self.relaxed = 0

    def run(self, max_iterations: int) -> OrbitResult:
        """Iterate from the initial guess until converged, failed, or ``max_iterations`` steps."""
        try:
            self.ret, self.F = self.eq.evaluate(self.z)
        except OrbitError as exc:
            return self.fail(exc.status, f"at the initial guess: {exc}", 0)
        self.res = float(np.max(np.abs(self.F))) if self.F.size else 0.0
        self.history.append(self.res)
        z_scale = 1.0 + float(np.max(np.abs(self.z)))
        while True:
            it = self.iterations
            if self.res <= self.tol:
                if self.accuracy is None:
                    self.accuracy = self._estimate_accuracy()
                if self.accuracy.noise > self.tol:
                    return self._unresolved(it)
                if self.res <= self.accuracy.resolved:
                    return self.converged(it)
            if it >= max_iterations:
                break
            failure = self.iterate(it, z_scale, max_iterations - it)
            if failure is not None:
                return self._above_resolution(self._stalled_above_tol(self._stuck_on_a_jump(failure)))
            if float(np.max(np.abs(self.z))) > 1e8 * z_scale:
                return self.fail(
                    "diverged",
                    f"iteration {self.iterations}: the iterates run away (|z| = {np.max(np.abs(self.z)):.3g})",
                    self.iterations,
                )
        if self.res <= self.tol:
            return self._above_resolution(self.fail("max_iterations", "", max_iterations))
        return self.fail(
            "max_iterations",
            f"no convergence in {max_iterations} iterations: residual {self.res:.3g} "
            f"> tol {self.tol:g} (history {[float(f'{v:.3g}') for v in self.history]})",
            max_iterations,
        )

    def _estimate_accuracy(self, scale: np.ndarray | None = None) -> MapAccuracy:
        """What the map resolves at the current iterate (``legsim.orbits.accuracy``), probed at
        ``scale`` (default the module's tiny probes; the refined map is evaluated only then)."""
        refined, words = refined_problem(self.p)
        x, _, memory = self.eq.unpack(self.z)
        fine = _Equations(refined, x, memory, ReturnMap(refined))
        return estimate_accuracy(
            self.z,
            self.F,
            lambda z: self.eq.evaluate(z)[1],
            None if scale is not None else (lambda z: fine.evaluate(z)[1]),
            words,
            self.eq.row_names,
            scale,
        )

    def _resolved_at_step_scale(self) -> MapAccuracy | None:
        """The map's noise measured with probes as large as the Newton step that failed, when
        that noise accounts for the residual (the map resolves no better at the scale of the
        correction the residual calls for); None otherwise."""
        if self.last_step is None or self.accuracy is None:
            return None
        coarse = self._estimate_accuracy(np.abs(self.last_step))
        if self.res > coarse.resolved:
            return None
        coarse.refinement, coarse.refined = self.accuracy.refinement, self.accuracy.refined
        return coarse

    def _unresolved(self, it: int) -> OrbitResult:
        """``map_unresolved``: the residual is within tol but the map's noise is not."""
        acc = self.accuracy
        assert acc is not None
        return self.fail(
            "map_unresolved",
            f"the residual {self.res:.3g} is within tol {self.tol:g} after {it} iteration(s), but the return map "
            f"does not resolve tol here: {acc.describe()}; no residual below that noise vouches for an orbit "
            f"(a jump of the return map at this point, e.g. transitions whose order rounding decides and "
            f"that change the return by that much), and a map with a jump has no multipliers and no "
            f"piecewise-linear derivative to give a stability verdict",
            it,
        )

    def _stuck_on_a_jump(self, failure: OrbitResult) -> OrbitResult:
        """A search that no Newton step advances (``diverged`` by ``_no_step``) above tol, where
        the return map's noise accounts for the residual: ``map_unresolved``, since the map
        jumps there (e.g. an event order or a graze that rounding decides) and no smaller residual
        would vouch for an orbit. The noise is probed with the tiny probes, then with probes as
        large as the shortest step tried: there a smooth map's second difference is 4^-backtracks
        of the curvature term that stopped the full step (~ the residual), a jump's is half the
        jump whatever the probe. Other failures stand as they are."""
        if failure.status != "diverged" or self.last_step is None or self.res <= self.tol:
            return failure
        tiny = self._estimate_accuracy()
        acc = tiny
        if self.res > tiny.resolved:
            coarse = self._estimate_accuracy(np.abs(self.last_step) / 2**self.max_backtracks)
            coarse.refinement, coarse.refined = tiny.refinement, tiny.refined
            acc = coarse
        if self.res > acc.resolved:
            # Said either way: a map that does resolve the residual leaves the divergence to the
            # iterate, not to noise of the map.
            self.accuracy = failure.map_accuracy = acc
            failure.message += (
                f"; the return map resolves {acc.resolved:.3g} here ({acc.describe()}), below the residual, so "
                f"the map's noise does not explain it"
            )
            return failure
        self.accuracy = acc
        result = self.fail(
            "map_unresolved",
            f"no Newton step lowers the residual {self.res:.3g} (> tol {self.tol:g}) after {failure.iterations} "
            f"iteration(s), and the return map does not resolve it here: {acc.describe()}; no residual below that "
            f"noise vouches for an orbit (a jump of the return map at this point, e.g. transitions whose order or "
            f"occurrence rounding decides and that change the return by that much), and a map with a jump has no "
            f"multipliers and no piecewise-linear derivative to give a stability verdict",
            failure.iterations,
        )
        return result

    def _stalled_above_tol(self, failure: OrbitResult) -> OrbitResult:
        """A search stalled above tol says what the map resolves there: whether tol is tighter
        than the map can resolve."""
        if failure.status != "stalled" or self.accuracy is not None:
            return failure
        self.accuracy = failure.map_accuracy = self._estimate_accuracy()
        if self.tol < self.accuracy.resolved:
            failure.message += (
                f"; tol {self.tol:g} is tighter than the return map resolves here "
                f"({self.accuracy.resolved:.3g}: {self.accuracy.describe()})"
            )
        return failure

    def _above_resolution(self, failure: OrbitResult) -> OrbitResult:
        """A failed refinement of an iterate within tol but above what the map resolves:
        converged when the Newton step is below rounding (the point solves the linearised
        equations in the least-squares sense, and the residual is their inconsistency, e.g. a
        conserved quantity the integrator conserves only to its error), else ``stalled`` at that
        iterate, saying so; other failures stand as they are."""
        acc = self.accuracy
        if acc is None or failure.residual > self.tol:
            return failure
        coarse = None if failure.status == "stalled" else self._resolved_at_step_scale()
        if coarse is not None:
            self.accuracy = coarse
            return self.converged(
                failure.iterations,
                f"residual {self.res:.3g} <= tol {self.tol:g} after {failure.iterations} iteration(s); no Newton "
                f"step lowers it, and at the scale of that step the return map resolves only {coarse.resolved:.3g} "
                f"({coarse.describe()})",
            )
        if failure.status == "stalled":
            return self.converged(
                failure.iterations,
                f"residual {self.res:.3g} <= tol {self.tol:g} after {failure.iterations} iteration(s); above what "
                f"the return map resolves ({acc.resolved:.3g}), but the Newton step is below rounding: the orbit "
                f"equations are consistent only to {self.res:.3g} (overdetermined, e.g. a conserved quantity the "
                f"integrator keeps to its own error)",
            )
        failure.status = "stalled"
        failure.message = (
            f"the residual {self.res:.3g} is within tol {self.tol:g} but above what the return map resolves "
            f"({acc.resolved:.3g}; {acc.describe()}), and Newton's method did not lower it to that "
            f"level" + (f" ({failure.message})" if failure.message else "") + ": the point is not an orbit "
            "to the map's accuracy (tol is looser than the map allows; a kink of the map at the orbit can "
            "also stop Newton's method)"
        )
        return failure

    def iterate(self, it: int, z_scale: float, allowed: int) -> OrbitResult | None:
        """One Newton step with backtracking, or where none lowers the residual, the watchdog's
        steps (at most ``allowed`` in all); the failed result when neither advances."""
        dz = self._newton_step(it)
        if isinstance(dz, OrbitResult):
            return dz
        self.last_step = dz
        trial = self._line_search(dz)
        if trial is not None:
            self.iterations += 1
        elif float(np.max(np.abs(dz))) > 1e-12 * z_scale:  # a step below rounding stalls (_no_step)
            trial = self._watchdog(dz, min(WATCHDOG_STEPS, allowed))
        if trial is None:
            return self._no_step(it, dz, z_scale)
        self.z, self.ret, self.F, self.res = trial
        self.history.append(self.res)
        return None

    def _newton_step(self, it: int) -> np.ndarray | OrbitResult:
        """The Gauss-Newton step dz at the current iterate, or the failed result (a singular or
        flat Jacobian, or one that cannot be computed)."""
        try:
            U, sv, Vt = self._decomposition(newton=True)
            if self.method == "saltation" and sv.size and np.all(np.isfinite(sv)) and sv[-1] <= NEAR_SINGULAR * sv[0]:
                # The Newton Jacobian's error (~1e-6 relative) could hide a singular one:
                # decide on the accurate Jacobian.
                U, sv, Vt = self._decomposition(newton=False)
        except OrbitError as exc:
            return self.fail(exc.status, f"iteration {it + 1}: {exc}", it)
        if sv.size == 0 or not np.all(np.isfinite(sv)):
            return self.fail("singular_jacobian", f"iteration {it + 1}: the Jacobian is not finite", it)
        if sv[0] == 0.0 and not self._near_orbit():
            return self._flat(it)
        if sv[-1] <= self.singular_tol * sv[0]:
            return self.fail("singular_jacobian", self._singular_message(it, sv, Vt[-1]), it)
        return _step(U, sv, Vt, self.F)

    def _evaluated(self, z: np.ndarray) -> tuple[np.ndarray, Return, np.ndarray, float] | None:
        """(z, its return, F(z), residual), or None where the return cannot be simulated."""
        try:
            ret, F = self.eq.evaluate(z)
        except OrbitError:
            return None
        return z, ret, F, float(np.max(np.abs(F)))

    def _watchdog(self, dz: np.ndarray, allowed: int) -> tuple[np.ndarray, Return, np.ndarray, float] | None:
        """Full Newton steps that may raise the residual for a while (Chamberlain's watchdog),
        tried where no halving of dz lowers it: the first iterate of z + dz and up to ``allowed``
        - 1 further full steps whose residual is below ``WATCHDOG_DECREASE`` of the current one,
        or None (the search then stays at the current iterate). Near an orbit where the map's
        event order switches (a symmetric gait) the map is piecewise smooth: a difference Jacobian
        mixes its pieces, and the step it gives can raise the residual although the steps after
        it converge, linearly, to the orbit. Each iterate must stay within ``WATCHDOG_GROWTH`` of
        the current residual."""
        trial = self._evaluated(self.z + dz)
        passed: list[float] = []
        for taken in range(1, allowed + 1):
            if trial is None or not trial[3] < WATCHDOG_GROWTH * self.res:
                return None
            if trial[3] < WATCHDOG_DECREASE * self.res:
                self.iterations += taken
                self.relaxed += taken
                self.history.extend(passed)
                return trial
            if taken == allowed:
                return None
            passed.append(trial[3])
            try:
                U, sv, Vt = self._decomposition(True, trial[0], trial[1])
            except OrbitError:
                return None
            if not (sv.size and np.all(np.isfinite(sv)) and sv[-1] > self.singular_tol * sv[0]):
                return None
            trial = self._evaluated(trial[0] + _step(U, sv, Vt, trial[2]))
        return None

    def _decomposition(
        self, newton: bool, z: np.ndarray | None = None, ret: Return | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The SVD (U, singular values, V^T) of dF/dz at z whose return is ret (default the
        current iterate); OrbitError when the Jacobian cannot be computed."""
        z, ret = (self.z, self.ret) if z is None else (z, ret)
        J, _ = self.eq.jacobian(z, ret, self.method, self.fd_step, newton=newton)  # type: ignore[arg-type]
        U, sv, Vt = np.linalg.svd(J, full_matrices=False)
        return U, sv, Vt

    def _line_search(self, dz: np.ndarray) -> tuple[np.ndarray, Return, np.ndarray, float] | None:
        """The first of z + dz, z + dz/2, ... (max_backtracks halvings) that lowers the residual."""
        lam = 1.0
        for _ in range(self.max_backtracks + 1):
            trial = self.z + lam * dz
            try:
                ret, F = self.eq.evaluate(trial)
                res = float(np.max(np.abs(F)))
            except OrbitError:
                res = math.inf
            if res < self.res:
                return trial, ret, F, res
            lam *= 0.5
        return None

    def _near_orbit(self) -> bool:
        """Whether the residual is small enough that a singular Jacobian means a family of orbits
        through the iterate rather than a degenerate map far from any orbit."""
        return self.res <= max(1e3 * self.tol, 1e-6)

    def _flat(self, it: int) -> OrbitResult:
        """``diverged`` for a Jacobian that is zero far from an orbit: no unknown moves the
        residual to first order, so no Newton step exists and no orbit is near the iterate."""
        x_now, params_now, _ = self.eq.unpack(self.z)
        return self.fail(
            "diverged",
            f"iteration {it + 1}: no Newton step reduces the residual {self.res:.3g}: the orbit equations "
            f"do not change with any unknown at the last iterate {self.rmap.show_state(x_now)}"
            + (f" with parameters {params_now}" if self.p.free else "")
            + " (their Jacobian is zero there), so there may be no periodic orbit near it",
            it,
        )

    def _singular_message(self, it: int, sv: np.ndarray, null: np.ndarray) -> str:
        names = self.p.unknown_names
        lead = ", ".join(f"{names[i]} ({null[i]:+.2f})" for i in np.argsort(-np.abs(null))[:3] if abs(null[i]) > 0.1)
        head = (
            f"iteration {it + 1}: the Jacobian of the orbit equations is singular (singular values "
            f"{sv[0]:.3g} .. {sv[-1]:.3g}, residual {self.res:.3g})"
        )
        if self._near_orbit():
            # Next to an orbit: a whole family of them passes through it.
            return (
                f"{head}: the orbit is not isolated along {lead}; a conserved quantity or symmetry leaves a "
                f"family of orbits: fix one of these coordinates or add a constraint (e.g. energy)"
            )
        # Far from any orbit the iterate may simply have wandered where the map degenerates.
        return (
            f"{head}: the iterate {self.rmap.show_state(self.eq.unpack(self.z)[0])} is still far from an orbit "
            f"and the return map degenerates there along {lead}: try another initial guess (or, if a conserved "
            f"quantity leaves a family of orbits, fix one of these coordinates or add a constraint)"
        )

    def _no_step(self, it: int, dz: np.ndarray, z_scale: float) -> OrbitResult:
        """``stalled`` when the Newton step is below rounding (the return map's noise limits the
        residual), ``diverged`` otherwise."""
        step_norm = float(np.max(np.abs(dz)))
        if step_norm <= 1e-12 * z_scale:
            return self.fail(
                "stalled",
                f"the residual stalls at {self.res:.3g} > tol {self.tol:g} after {it} iteration(s): the "
                f"Newton step ({step_norm:.2g}) is below rounding, so the return map's own noise "
                f"(rounding, and the integrator's steps: {self.p.integrator_label}) limits "
                f"the residual: raise tol",
                it,
            )
        x_now, params_now, _ = self.eq.unpack(self.z)
        return self.fail(
            "diverged",
            f"iteration {it + 1}: no Newton step (lengths 1 .. 1/{2**self.max_backtracks}) reduces the "
            f"residual {self.res:.3g}, nor do up to {WATCHDOG_STEPS} full steps on from it halve it; there may "
            f"be no periodic orbit near the last iterate "
            f"{self.rmap.show_state(x_now)}" + (f" with parameters {params_now}" if self.p.free else ""),
            it,
        )

    def converged(self, it: int, message: str | None = None) -> OrbitResult:
        """The converged result with the Jacobian and multipliers at the fixed point; ``message``
        says how it converged (default: within tol and what the map resolves). It is given here,
        not set afterwards, so that a failure of the multipliers (``add_multipliers``) extends it
        rather than being overwritten by it."""
        ret = self.ret
        assert ret is not None
        try:
            DP: np.ndarray | CheckedJacobian = (
                jacobian_saltation(self.p, ret)
                if self.method == "saltation"
                else jacobian_fd_checked(
                    self.p,
                    ret.x_start,
                    ret.parameters,
                    self.fd_step,
                    rmap=self.rmap,
                    memory=ret.memory_start,
                    base=ret.end,
                )
            )
        except OrbitError as exc:
            return self.fail(exc.status, f"converged (residual {self.res:.3g}) but the Jacobian failed: {exc}", it)
        result = self._result(
            "converged",
            message
            or f"residual {self.res:.3g} <= tol {self.tol:g} and within what the return map resolves after "
            f"{it} iteration(s)"
            + self._relaxed_words(),
            ret.x_start,
            ret.parameters,
            it,
            ret.memory_start,
        )
        result = add_multipliers(result, self.p, ret, DP)
        result.evaluations = self.rmap.evaluations  # a verdict on sampled pieces evaluates the map further
        return result

    def _relaxed_words(self) -> str:
        """What the watchdog did, for a converged search's message ('' when it took no step)."""
        if not self.relaxed:
            return ""
        return (
            f" ({self.relaxed} of them full steps past a rise of the residual: the return map is not smooth near "
            f"the orbit, e.g. an event order switching there, where Newton's method converges only linearly)"
        )

    def fail(self, status: str, message: str, iterations: int) -> OrbitResult:
        """A result that is not converged, at the current iterate."""
        x_now, params_now, memory_now = self.eq.unpack(self.z)
        return self._result(status, message, x_now, params_now, iterations, memory_now)

    def _result(
        self, status: str, message: str, x: np.ndarray, params: Mapping[str, float], iterations: int, memory: np.ndarray
    ) -> OrbitResult:
        p = self.p
        result = OrbitResult(
            status=status,
            message=message,
            mode=p.bound.mode,
            state_names=p.names,
            fixed_point=np.asarray(x, dtype=float).copy(),
            parameters=dict(params),
            residual=self.res,
            iterations=iterations,
            history=list(self.history),
            trivial_multipliers=p.trivial_multipliers,
            evaluations=self.rmap.evaluations,
            jacobian_method=self.method,
            section=p.section.label,
            free=tuple(p.free),
            memory=np.asarray(memory, dtype=float).copy(),
            memory_names=p.memory_names,
            memory_units=p.memory_units,
            map_accuracy=self.accuracy,
        )
        if self.accuracy is not None and status == "converged":
            result.warnings.extend(self.accuracy.warnings(self.tol))
        if self.ret is not None:
            result.period = self.ret.flow_time
            result.return_time = self.ret.time
            result.step_length = self.ret.step_length
            result.transitions = [tr.name for tr in self.ret.transitions]
        return result
