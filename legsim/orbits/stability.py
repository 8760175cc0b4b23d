"""The multipliers of a found orbit and the verdict on its stability: the Floquet multipliers
of the return map's Jacobian restricted to the section, and where that Jacobian is not
differentiable (its one-sided differences disagree), each side's multipliers and the
piecewise-linear verdict (``piecewise``).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..control import ControlLaw
from .errors import OrbitError
from .jacobians import field_at, floquet_multipliers
from .kinks import CheckedJacobian
from .piecewise import Verdict, piecewise_verdict, section_matrices
from .problem import OrbitProblem, Return
from .result import OrbitResult
from .sampled_pieces import PieceSampler, sampled_verdict


def add_multipliers(
    result: OrbitResult, problem: OrbitProblem, ret: Return, DP: np.ndarray | CheckedJacobian
) -> OrbitResult:
    """Fill in the Jacobian, its restriction to the section and the multipliers (and, for a
    checked finite-difference Jacobian, its verdict on differentiability); a field that vanishes
    at the fixed point (an equilibrium) turns the result into that failure."""
    f = _closed_loop_field(problem, ret)
    checked, J = (DP, DP.central) if isinstance(DP, CheckedJacobian) else (None, DP)
    try:
        mu, M = floquet_multipliers(J, f, problem.cyclic_idx)
    except OrbitError as exc:
        result.status, result.message = exc.status, f"{result.message}; but {exc}"
        return result
    result.jacobian = J
    result.section_jacobian = M
    result.multipliers = mu
    if checked is not None:
        _add_differentiability(result, problem, checked, f)
    return result


def _add_differentiability(result: OrbitResult, problem: OrbitProblem, checked: CheckedJacobian, f: np.ndarray) -> None:
    """The check's verdict; when a column is kinked, each side's multipliers and a warning."""
    result.differentiable = checked.differentiable
    all_names = list(problem.names) + list(problem.memory_names)
    if checked.differentiable is None:
        result.warnings.append(
            f"the differentiability check could not compare the one-sided differences in the column(s) of "
            f"{', '.join(checked.unchecked_names(all_names))} (a simulation of its stencil failed there): "
            f"their Jacobian columns are one-sided or unchecked, and a kink there would not be seen"
        )
    if checked.differentiable is not False:
        return
    names = checked.kinked_names(all_names)
    result.kinked_coordinates = names
    result.multipliers_forward = floquet_multipliers(checked.forward, f, problem.cyclic_idx)[0]
    result.multipliers_backward = floquet_multipliers(checked.backward, f, problem.cyclic_idx)[0]
    radius = {side: _radius(result, side) for side in ("forward", "backward")}
    result.piecewise = piecewise_verdict(
        checked.forward,
        checked.backward,
        checked.central,
        checked.orders,
        f,
        problem.cyclic_idx,
        problem.trivial_multipliers,
    )
    if len(checked.seen_orders) > 2 and checked.around is not None:
        result.piecewise = _sampled_verdict(problem, checked, f)
    result.warnings.append(
        f"the return map is not differentiable at the orbit: the forward and backward differences of "
        f"its Jacobian disagree in the column(s) of {', '.join(names)} (a kink, e.g. transitions that "
        f"switch order there), so the multipliers do not decide stability: spectral "
        f"radius {result.spectral_radius:.4g} (central), {radius['forward']:.4g} (forward), "
        f"{radius['backward']:.4g} (backward differences); piecewise-linear verdict: "
        f"{result.piecewise.kind} ({result.piecewise.reason})"
    )


def _sampled_verdict(problem: OrbitProblem, checked: CheckedJacobian, f: np.ndarray) -> Verdict:
    """The verdict on the pieces found by sampling (``sampled_pieces``) around the checked
    Jacobian's point, where more than two event orders meet at the orbit."""
    around = checked.around
    assert around is not None  # the caller checks
    sampler = PieceSampler(around.evaluate, around.start, around.base, checked.checked, around.steps, checked.central)

    def project(matrices: list[np.ndarray]) -> list[np.ndarray] | str:
        found = section_matrices(matrices, f, problem.cyclic_idx, problem.trivial_multipliers)
        return found if isinstance(found, str) else found[0]

    return sampled_verdict(sampler, project)


def _radius(result: OrbitResult, side: str) -> float:
    """The spectral radius of one side's multipliers, without the trivial ones."""
    one_sided = replace(result, multipliers=getattr(result, f"multipliers_{side}"))
    radius = one_sided.spectral_radius
    assert radius is not None  # its multipliers were just set
    return radius


def _closed_loop_field(problem: OrbitProblem, ret: Return) -> np.ndarray:
    """The field at the fixed point, shape (n + m,): with a controller, the closed loop's with
    the controller restored to the orbit's memory, which stays constant along the flow (zeros)."""
    system, control = problem.instantiate(ret.parameters)
    mode = problem.bound.mode
    if problem.controller is None:
        return field_at(system.mode(mode), control, 0.0, ret.x_start)
    controller = problem.restored_controller(ret.parameters, ret.memory_start)
    if isinstance(controller, ControlLaw):
        u = law_input(controller, mode, 0.0, ret.x_start, ret.memory_start)
    else:
        controller.reset(mode, 0.0, ret.x_start)
        u = controller(mode, 0.0, ret.x_start)
    f = np.asarray(system.mode(mode).field(0.0, ret.x_start, u), dtype=float)
    return np.concatenate([f, np.zeros(problem.n_memory)])


def law_input(law: ControlLaw, mode: str, t: float, x: np.ndarray, memory: np.ndarray) -> np.ndarray:
    """A ``ControlLaw``'s input (shape (inputs,)) entering ``mode`` at (t, x) with ``memory``:
    its entry function first, then its control, as a run does."""
    p = law.params_for(mode)
    x = np.ascontiguousarray(x, dtype=float)
    memory = np.ascontiguousarray(memory, dtype=float)
    if law.enter is not None:
        entered = np.empty_like(memory)
        law.enter(float(t), x, memory, p, entered)
        memory = entered
    u = np.zeros(law.inputs)
    law.control(float(t), x, memory, p, u)
    return u
