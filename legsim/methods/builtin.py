"""The built-in methods, by name: Euler, the two-stage midpoint and Heun methods, classical RK4,
and the embedded pairs Bogacki-Shampine 3(2), Dormand-Prince 5(4) and DOP853 8(5,3), each with
its continuous extension where it has one."""

from __future__ import annotations

import numpy as np

from ..errors import SimulationError
from . import dop853_data as d853
from .tableau import DenseOutput, Tableau, check_tableau, tableau

EULER = tableau("euler", 1, [0.0], [[]], [1.0])
MIDPOINT = tableau("rk2", 2, [0.0, 0.5], [[], [0.5]], [0.0, 1.0])
HEUN = tableau("heun", 2, [0.0, 1.0], [[], [1.0]], [0.5, 0.5])
RK4 = tableau("rk4", 4, [0.0, 0.5, 0.5, 1.0], [[], [0.5], [0.0, 0.5], [0.0, 0.0, 1.0]], [1 / 6, 1 / 3, 1 / 3, 1 / 6])

#: Bogacki-Shampine's free cubic Hermite interpolant (the one scipy's RK23 uses).
_BS32_DENSE = DenseOutput(
    3, np.array([[1.0, -4 / 3, 5 / 9], [0.0, 1.0, -2 / 3], [0.0, 4 / 3, -8 / 9], [0.0, -1.0, 1.0]])
)
BOGACKI_SHAMPINE = tableau(
    "bs32",
    3,
    [0.0, 0.5, 0.75, 1.0],
    [[], [0.5], [0.0, 0.75], [2 / 9, 1 / 3, 4 / 9]],
    [2 / 9, 1 / 3, 4 / 9, 0.0],
    b_hat=[7 / 24, 1 / 4, 1 / 3, 1 / 8],
    error_order=2,
    fsal=True,
    dense=_BS32_DENSE,
)

#: Shampine's free quartic interpolant for Dormand-Prince (the one scipy's RK45 uses).
_DOPRI5_DENSE = DenseOutput(
    4,
    np.array(
        [
            [1, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
            [0, 0, 0, 0],
            [0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799],
            [0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
            [0, 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632],
            [0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
            [0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423],
        ],
        dtype=float,
    ),
)
DORMAND_PRINCE = tableau(
    "dopri5",
    5,
    [0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0],
    [
        [],
        [1 / 5],
        [3 / 40, 9 / 40],
        [44 / 45, -56 / 15, 32 / 9],
        [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729],
        [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656],
        [35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84],
    ],
    [35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0.0],
    b_hat=[5179 / 57600, 0.0, 7571 / 16695, 393 / 640, -92097 / 339200, 187 / 2100, 1 / 40],
    error_order=4,
    fsal=True,
    dense=_DOPRI5_DENSE,
)


def _dop853_matrix() -> np.ndarray:
    A = np.zeros((d853.EXTENDED_STAGES, d853.EXTENDED_STAGES))
    for i, row in d853.A_ROWS.items():
        for j, weight in row.items():
            A[i, j] = weight
    return A


def _dop853_dense(A: np.ndarray, b: np.ndarray) -> DenseOutput:
    """DOP853's seventh-order interpolant in the form x + h sum_i w_i(theta) k_i.

    Hairer writes it as x + F0 th + F1 th (1 - th) + F2 th^2 (1 - th) + ..., nested in th and
    1 - th, with rows F linear in the 16 stages (the first three from b and the stages at the
    step's ends, the last four the rows D); expanding the nesting once gives the weights P."""
    power, n_all, s = d853.INTERPOLATOR_POWER, d853.EXTENDED_STAGES, d853.STAGES + 1
    rows = np.zeros((power, n_all))
    rows[0, :s] = b
    rows[1, 0] += 1.0
    rows[1, :s] -= b
    rows[2, :s] += 2.0 * b
    rows[2, 0] -= 1.0
    rows[2, s - 1] -= 1.0  # the 13th stage: f at the new point
    rows[3:] = np.array(d853.D)
    # Each F row's polynomial in theta: the nesting multiplies by th and (1 - th) in turn, last row first.
    monomials = np.zeros((power, power + 1))
    for r in range(power):
        poly = np.zeros(power + 1)
        for i, row in enumerate(reversed(range(power))):
            if row == r:
                poly[0] += 1.0
            shifted = np.concatenate([[0.0], poly[:-1]])
            poly = shifted if i % 2 == 0 else poly - shifted
        monomials[r] = poly
    P = rows.T @ monomials[:, 1:]
    return DenseOutput(7, P, np.array(d853.C[s:]), A[s:])


def _dop853() -> Tableau:
    """The 12 stages of DOP853 plus a 13th at the new point (row = b, c = 1), which makes it
    FSAL. Its error norm blends the fifth- and third-order estimates as Hairer's code does; the
    step exponent is -1/8 (error_order 7: the blended norm scales as h^8)."""
    s = d853.STAGES + 1
    full = _dop853_matrix()
    A = np.zeros((s, s))
    A[: s - 1, : s - 1] = full[: s - 1, : s - 1]
    A[s - 1, : s - 1] = d853.B
    c = np.concatenate([d853.C[: s - 1], [1.0]])
    b = np.concatenate([d853.B, [0.0]])
    return Tableau("dop853", 8, c, A, b, np.array(d853.E5), 7, True, _dop853_dense(full, b), np.array(d853.E3))


DOP853 = _dop853()


def _rosenbrock(
    name: str,
    order: int,
    error_order: int,
    gamma: float,
    alpha: list[list[float]],
    Gamma: list[list[float]],
    b: list[float],
    b_hat: list[float],
) -> Tableau:
    """A Rosenbrock W-method from its published coefficients (Hairer and Wanner II, Sec. IV.7:
    k_i = h f(x + sum alpha_ij k_j) + h J sum gamma_ij k_j, x_new = x + sum b_i k_i, Gamma with
    gamma on its diagonal) in the form of ``Tableau``, without products by J: with
    Gamma^-1 written out (HW's transformed stages), A = gamma alpha Gamma^-1,
    G = gamma (diag(1/gamma) - Gamma^-1), b = gamma b Gamma^-1, and the row sums of Gamma for the
    time derivative of a non-autonomous field (``time_weights``)."""
    s = len(b)
    G_full = np.array(Gamma, dtype=float) + gamma * np.eye(s)
    inv = np.linalg.inv(G_full)
    weights = gamma * (np.array(b) @ inv)
    embedded = gamma * (np.array(b_hat) @ inv)
    return Tableau(
        name,
        order,
        np.array(alpha, dtype=float).sum(axis=1),
        np.tril(gamma * (np.array(alpha, dtype=float) @ inv), -1),
        weights,
        b_err=weights - embedded,
        error_order=error_order,
        gamma=gamma,
        G=np.tril(gamma * (np.eye(s) / gamma - inv), -1),
        time_weights=G_full.sum(axis=1),
    )


#: ROS34PW2 (Rang and Angermann, BIT 45, 2005): a four-stage Rosenbrock W-method of order 3 with
#: an embedded order-2 solution, L-stable, and of order 3 with any Jacobian approximation to
#: order 2, so a Jacobian can serve many steps.
ROS34PW2 = _rosenbrock(
    "ros34pw2",
    3,
    2,
    4.3586652150845900e-01,
    [
        [0.0, 0.0, 0.0, 0.0],
        [8.7173304301691801e-01, 0.0, 0.0, 0.0],
        [8.4457060015369423e-01, -1.1299064236484185e-01, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ],
    [
        [0.0, 0.0, 0.0, 0.0],
        [-8.7173304301691801e-01, 0.0, 0.0, 0.0],
        [-9.0338057013044082e-01, 5.4180672388095326e-02, 0.0, 0.0],
        [2.4212380706095346e-01, -1.2232505839045147e00, 5.4526025533510214e-01, 0.0],
    ],
    [2.4212380706095346e-01, -1.2232505839045147e00, 1.5452602553351020e00, 4.3586652150845900e-01],
    [3.7810903145819369e-01, -9.6042292212423178e-02, 0.5, 2.1793326075422950e-01],
)

METHODS: dict[str, Tableau] = {
    t.name: t for t in (EULER, MIDPOINT, HEUN, RK4, BOGACKI_SHAMPINE, DORMAND_PRINCE, DOP853, ROS34PW2)
}
ALIASES = {"midpoint": "rk2", "rk45": "dopri5", "dp54": "dopri5", "rk23": "bs32"}

#: scipy's ``solve_ivp`` names, spelled as scipy spells them: they imply error-controlled steps,
#: so without rtol/atol a run by one of these names takes scipy's default tolerances
#: (``ADAPTIVE_DEFAULTS``); legsim's own names (``dopri5``, ``bs32``, ``dop853``) step by h unless
#: a tolerance is given.
SCIPY_NAMES = ("RK45", "RK23", "DOP853")
#: scipy's default tolerances (rtol, atol) of solve_ivp.
ADAPTIVE_DEFAULTS = (1e-3, 1e-6)


def get_method(method: str | Tableau) -> Tableau:
    """Look a method up by name (``euler``, ``rk2``/``midpoint``, ``heun``, ``rk4``,
    ``bs32``/``rk23``, ``dopri5``/``rk45``, ``dop853``; case-insensitive) or pass a ``Tableau``
    through."""
    if isinstance(method, Tableau):
        try:
            return check_tableau(method)
        except ValueError as exc:
            raise SimulationError(f"method: {exc}") from None
    if not isinstance(method, str):
        raise SimulationError(f"method must be a name or a Tableau, got {type(method).__name__}")
    key = ALIASES.get(method.lower(), method.lower())
    if key not in METHODS:
        raise SimulationError(f"unknown method '{method}'; choose one of {sorted(METHODS) + sorted(ALIASES)}")
    return METHODS[key]


def dense_output(method: Tableau) -> DenseOutput | None:
    """The continuous extension of ``method``, or None when it has none."""
    return method.dense
