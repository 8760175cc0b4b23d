"""The work-precision cases: a system, its reference, and the sweep of each method's knobs.

A case names the system legsim simulates (as compiled model functions where it has them), the
system the event-driven baseline runs on, the position coordinates of the error of paper 000
eq. (30), the reference, and the runs of the sweep. References are closed forms where they
exist (oscillator, bouncing ball); otherwise a converged event-driven run (DOP853 at tolerance
1e-12 with its own dense output) whose error is estimated against a run 100x looser.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..builders import get_builder
from ..errors import LegsimError
from ..hybrid import HybridSystem
from .names import CASE_NAMES

#: solve_ivp methods in the sweeps (explicit pairs: these models are not stiff).
IVP_METHODS = ("RK45", "DOP853")
#: Adaptive pairs of the relaxed integrator.
ADAPTIVE_PAIRS = ("bs32", "dopri5", "dop853")


class BenchError(LegsimError):
    """A benchmark could not be set up or run (unknown case, missing robot, bad option)."""


def relaxed_method(name: str) -> str:
    """The ``simulate`` method of a ``relaxed-<name>`` run (``<name>-zeno`` for a run with the
    default continuation)."""
    return name.removesuffix("-zeno")


@dataclass(frozen=True)
class RunSpec:
    """One run of a sweep.

    kind: ``relaxed``, ``ps`` or ``solve_ivp``; method: the CSV name (``relaxed-rk4``, ``ps``,
    ``solve_ivp-DOP853``, ...); h: step (s), the nominal/initial step for relaxed runs (nan for
    solve_ivp); eps: strip width (guard units, nan where none); tol: rtol = atol of
    error-controlled runs (nan otherwise); landing: relaxed landing rule; max_step: solve_ivp's
    largest step (s): with long steps solve_ivp misses a guard crossed and recrossed within one
    step (it only sees sign changes between step ends), so the sweep tries a bound too.
    zeno: relaxed run with the default Zeno continuation (``simulate(continuation=True)``: the
    case's ``zeno_system`` enters its resting or sticking mode where its impacts accumulate,
    window h + eps); its method name ends in ``-zeno``. Every other relaxed run is the paper's
    relaxed execution, ``continuation=False``.
    """

    kind: str
    method: str
    h: float = math.nan
    eps: float = math.nan
    tol: float = math.nan
    landing: str = "aim"
    max_step: float = math.inf
    zeno: bool = False


@dataclass
class Target:
    """A speed target: at error <= level, ``baseline`` family time / relaxed time >= ratio.

    relaxed: which relaxed runs compete: ``all``, ``plain`` (no Zeno continuation) or ``zeno``.
    """

    name: str
    level: float
    baseline: str  # "ps" or "solve_ivp"
    ratio: float
    relaxed: str = "all"


@dataclass
class Case:
    """Everything one work-precision case needs."""

    name: str
    description: str
    system: HybridSystem
    ivp_system: HybridSystem  # the system solve_ivp runs (its Python callables)
    mode: str
    x0: np.ndarray
    t_final: float
    positions: tuple[int, ...]
    position_names: tuple[str, ...]
    reference_positions: Callable[[np.ndarray], np.ndarray]  # times (N,) -> (N, len(positions))
    reference_note: str
    runs: list[RunSpec]
    targets: list[Target]
    ps: dict[str, float] | None = None
    reference_execution: Any = None  # anything with sample(times), for rho
    rho_points: int | None = None  # default of the bench when None
    max_transitions: int = 1_000_000
    info: dict[str, Any] = field(default_factory=dict)
    # (system, control) of the runs with continuation (RunSpec.zeno); None: the case has none.
    zeno_system: tuple[HybridSystem, Any] | None = None
    # The control of every run (the oscillator's forcing law, also callable as u(t, x) for
    # solve_ivp); None: none.
    control: Any = None


# ----------------------------------------------------------------------------------------------
# Sweeps
# ----------------------------------------------------------------------------------------------
def _grid(kind: str, method: str, hs, epss, landing: str = "aim") -> list[RunSpec]:
    return [RunSpec(kind, method, float(h), float(e), math.nan, landing) for h in hs for e in epss]


def relaxed_sweep(
    h_ranges: dict[str, tuple[float, ...]],
    epss: tuple[float, ...] | dict[str, tuple[float, ...]],
    tols: tuple[float, ...],
    adaptive_eps: tuple[float, ...],
    h_adaptive: float | tuple[float, ...],
    pair_landing: str = "aim",
) -> list[RunSpec]:
    """Fixed-step methods on an h x eps grid (eps per method when a dict); adaptive pairs over
    tolerances x eps, with h the initial and largest step (each of ``h_adaptive``: the robots
    sweep the same largest steps that solve_ivp's ``max_step`` gets), landing by
    ``pair_landing`` (``dense`` where the fields are Python; the compiled kernel aims)."""
    runs: list[RunSpec] = []
    for name, hs in h_ranges.items():
        runs += _grid("relaxed", f"relaxed-{name}", hs, epss[name] if isinstance(epss, dict) else epss)
    h_largest = (h_adaptive,) if isinstance(h_adaptive, float) else h_adaptive
    for pair in ADAPTIVE_PAIRS:
        for h in h_largest:
            for tol in tols:
                for eps in adaptive_eps:
                    runs.append(RunSpec("relaxed", f"relaxed-{pair}", h, eps, tol, pair_landing))
    return runs


def ivp_sweep(tols: tuple[float, ...], max_steps: tuple[float, ...] = (math.inf,)) -> list[RunSpec]:
    return [
        RunSpec("solve_ivp", f"solve_ivp-{m}", math.nan, math.nan, tol, "", ms)
        for m in IVP_METHODS
        for tol in tols
        for ms in max_steps
    ]


def zeno_sweep(
    hs: dict[str, tuple[float, ...]], epss: tuple[float, ...], tols: tuple[float, ...] = (), h_adaptive: float = 1e-2
) -> list[RunSpec]:
    """Runs with the default continuation (``relaxed-<name>-zeno``): fixed-step methods on
    h x eps, dopri5 over tolerances x eps with ``h_adaptive`` the initial and largest step (the
    window is h + eps, so the adaptive runs need a small largest step)."""
    runs = [
        RunSpec("relaxed", f"relaxed-{name}-zeno", float(h), float(e), zeno=True)
        for name, grid in hs.items()
        for h in grid
        for e in epss
    ]
    runs += [
        RunSpec("relaxed", "relaxed-dopri5-zeno", h_adaptive, float(e), float(tol), zeno=True)
        for tol in tols
        for e in epss
    ]
    return runs


def ps_sweep(hs: tuple[float, ...]) -> list[RunSpec]:
    return [RunSpec("ps", "ps", float(h)) for h in hs]


# ----------------------------------------------------------------------------------------------
# Speed targets (ratios measured in one bench run)
# ----------------------------------------------------------------------------------------------
def targets_for(name: str, quick: bool = False) -> list[Target]:
    """The speed targets checked on case ``name``."""
    if name == "oscillator-ex1":
        return [
            Target("Ex.1 error <= 1e-3: time(PS) / time(relaxed)", 1e-3, "ps", 20.0),
            Target("Ex.1 error <= 1e-6: time(best solve_ivp) / time(relaxed)", 1e-6, "solve_ivp", 1.0),
        ]
    if name == "oscillator-ex2":
        # The plain relaxed integrator chatters where the exact mass sticks (its error floor is
        # ~1e-6 m at eps = 2e-7); the -zeno runs take the model's continuation there (the default).
        return [
            Target("Ex.2 error <= 1e-6: time(PS) / time(relaxed, plain or Zeno continuation)", 1e-6, "ps", 10.0),
            Target(
                "Ex.2 error <= 1e-6: time(PS) / time(plain relaxed, no continuation)", 1e-6, "ps", 10.0, relaxed="plain"
            ),
        ]
    if name == "bouncing-ball":
        return [Target("ball error <= 1e-6: time(best solve_ivp) / time(relaxed)", 1e-6, "solve_ivp", 1.0)]
    if name in ("pronk", "double-pendulum"):
        # The compiled kernel's design target (docs/targets.md): ten times the best solve_ivp.
        levels = (1e-3,) if quick else (1e-3, 1e-5, 1e-7)
        return [
            Target(f"{name} error <= {lv:g}: time(best solve_ivp) / time(relaxed)", lv, "solve_ivp", 10.0)
            for lv in levels
        ]
    raise BenchError(f"unknown case {name!r}; choose one of {', '.join(CASE_NAMES)}")


# ----------------------------------------------------------------------------------------------
# The cases
# ----------------------------------------------------------------------------------------------
def _oscillator(example: str, quick: bool) -> Case:
    from ..systems.oscillator import EXAMPLES, OscillatorReference, forcing, make_system

    p = EXAMPLES[example]
    system = make_system(p["omega"], p["a"], p["x_max"], p["c"], p["mass"])
    control = forcing(p["amplitude"], p["frequency"])
    x0, t_max = np.array([p["x0"], p["xd0"]]), float(p["t_max"])
    ref = OscillatorReference.example(example)
    ps = {key: p[key] for key in ("a", "omega", "c", "x_max", "amplitude", "frequency", "x0", "xd0", "mass")}
    targets = targets_for(f"oscillator-{example}", quick)
    t_final, runs = _oscillator_runs(example, quick, t_max)
    name = f"oscillator-{example}"

    return Case(
        name=name,
        description=(
            f"forced oscillator with a stop, paper 000 Table I Example {example[-1]} (t in [0, {t_final:.4g}] s)"
        ),
        system=system,
        ivp_system=system,
        mode="free",
        x0=x0,
        t_final=t_final,
        positions=(0,),
        position_names=("x",),
        reference_positions=lambda t: ref.states(t)[:, :1],
        reference_note="closed form (eq. (28) with impacts, sticking and Zeno sums: OscillatorReference)",
        runs=runs,
        targets=targets,
        ps=ps,
        reference_execution=ref,
        # The model names the stop's continuation too (stick, release at the forcing's sign
        # change), compiled as the rest of it.
        zeno_system=(system, control) if example == "ex2" else None,
        control=control,
    )


def _oscillator_runs(example: str, quick: bool, t_max: float) -> tuple[float, list[RunSpec]]:
    """The oscillator case's t_final (s, at most the example's ``t_max``) and its sweep."""
    if quick:
        # Ex.2 keeps its whole 4 pi s: its second sticking phase is where the plain run chatters.
        t_final = min(t_max, 2.0 * math.pi) if example == "ex1" else t_max
        runs = (
            _grid("relaxed", "relaxed-rk4", (1e-2, 3e-3), (1e-6,))
            + _grid("relaxed", "relaxed-rk2", (1e-2,), (1e-6,))
            + [RunSpec("relaxed", "relaxed-dopri5", 0.1, 1e-6, 1e-6)]
            + ps_sweep((1e-3, 1e-4))
        )
        if example == "ex1":
            runs.append(RunSpec("solve_ivp", "solve_ivp-DOP853", math.nan, math.nan, 1e-6, "", 0.05))
        else:
            runs += _grid("relaxed", "relaxed-rk4", (1e-2,), (2e-7,)) + zeno_sweep({"rk4": (1e-2,)}, (1e-6, 2e-7))
    elif example == "ex1":
        t_final = t_max
        # The error is about 150 eps (the hold of eps - tau seconds at ~30 m/s) plus the method's.
        runs = relaxed_sweep(
            {"euler": (1e-3, 1e-4, 1e-5), "rk2": (1e-2, 3e-3, 1e-3, 3e-4), "rk4": (1e-1, 3e-2, 1e-2, 3e-3, 1e-3)},
            {"euler": (1e-7, 1e-9), "rk2": (1e-5, 1e-7, 1e-9, 1e-11), "rk4": (1e-5, 1e-7, 1e-9, 1e-11)},
            (1e-4, 1e-6, 1e-8, 1e-10, 1e-12),
            (1e-7, 1e-9, 1e-11),
            0.1,
        )
        runs += ps_sweep((1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5, 3e-6))
        runs += ivp_sweep((1e-4, 1e-6, 1e-8, 1e-10, 1e-12), (math.inf, 0.05))
    else:
        t_final = t_max
        # The error is about 0.4 eps; sticking costs a strip crossing every ~sqrt(2 eps / F) s.
        epss = (1e-4, 1e-5, 1e-6, 3e-7, 1e-7)
        runs = relaxed_sweep(
            {"euler": (1e-3, 1e-4), "rk2": (1e-2, 1e-3), "rk4": (1e-1, 3e-2, 2e-2, 1e-2, 1e-3)},
            epss,
            (1e-6, 1e-9),
            (1e-6, 1e-7),
            0.1,
        )
        runs += ps_sweep((1e-2, 1e-3, 1e-4, 3e-5, 1e-5, 5e-6, 2e-6, 1e-6))
        # With the chatter gone RK4's own error decides: below 1e-6 up to h = 0.02 (window 0.02 s).
        runs += zeno_sweep({"rk2": (1e-2, 1e-3), "rk4": (1e-1, 3e-2, 2e-2, 1e-2, 1e-3)}, epss, (1e-6, 1e-9))
        # No solve_ivp: the mass starts at rest on the stop, pushed into it, and an event-driven
        # simulator can only fire zero-time impacts there forever (it has no sticking mode).
    return t_final, runs


def _bouncing_ball(quick: bool) -> Case:
    from ..systems.bouncing_ball import BouncingBallReference, make_system

    g, c = 9.81, 0.8
    system = make_system(g, c)
    ref = BouncingBallReference(g, c, 1.0, 0.0)
    # Before the Zeno time (4.06 s): the event-driven baseline cannot pass it.
    t_final = 1.0 if quick else 3.0
    if quick:
        runs = (
            _grid("relaxed", "relaxed-rk4", (1e-2,), (1e-6,))
            + _grid("relaxed", "relaxed-euler", (1e-3,), (1e-6,))
            + [RunSpec("solve_ivp", "solve_ivp-RK45", math.nan, math.nan, 1e-6)]
        )
    else:
        runs = relaxed_sweep(
            {"euler": (1e-3, 1e-4, 1e-5), "rk2": (1e-2, 1e-3, 1e-4), "rk4": (1e-1, 1e-2, 1e-3)},
            (1e-5, 1e-7, 1e-9, 1e-11),
            (1e-6, 1e-9),
            (1e-7, 1e-10),
            0.1,
        )
        runs += ivp_sweep((1e-4, 1e-6, 1e-8, 1e-10, 1e-12))
    return Case(
        name="bouncing-ball",
        description=f"ball dropped from 1 m onto a floor with restitution {c} (t in [0, {t_final}] s, before Zeno)",
        system=system,
        ivp_system=system,
        mode="flight",
        x0=np.array([1.0, 0.0]),
        t_final=t_final,
        positions=(0,),
        position_names=("z",),
        reference_positions=lambda t: ref.states(t)[:, :1],
        reference_note="closed form (BouncingBallReference)",
        runs=runs,
        targets=targets_for("bouncing-ball", quick),
        reference_execution=ref,
    )


def _robot(name: str, quick: bool) -> Case:
    model, positions, t_final, description = _robot_model(name, quick)
    system, mode = model.system, model.initial_mode
    x0 = np.array([model.initial_state[n] for n in system.state_names(mode)])
    ref_tol = 1e-10 if quick else 1e-12
    reference, ref_positions, estimate = _robot_reference(name, system, x0, mode, t_final, positions, ref_tol)
    if quick:
        runs = [
            *_grid("relaxed", "relaxed-rk4", (1e-2,), (1e-4,)),
            RunSpec("relaxed", "relaxed-dopri5", 0.1, 1e-6, 1e-6, "dense"),
            RunSpec("solve_ivp", "solve_ivp-DOP853", math.nan, math.nan, 1e-6, "", 0.05),
        ]
    else:
        # Both sides get the same largest steps (solve_ivp also unbounded): a long trial step
        # puts the pronk's hip through the ground, which the relaxed integrator shortens like
        # any step that leaves its domain, and which ends a solve_ivp run (model_breakdown).
        runs = relaxed_sweep(
            {"rk2": (3e-3, 1e-3, 3e-4), "rk4": (3e-2, 1e-2, 3e-3, 1e-3)},
            (1e-3, 1e-5, 1e-7),
            (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-10),
            (1e-6, 1e-9),
            (0.2, 0.1, 0.05),
            pair_landing="dense",
        )
        runs += ivp_sweep((1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-10), (math.inf, 0.2, 0.1, 0.05))
    return Case(
        name=name,
        description=description,
        system=system,
        ivp_system=system,
        mode=mode,
        x0=x0,
        t_final=t_final,
        positions=positions,
        position_names=tuple(system.state_names(mode)[i] for i in positions),
        reference_positions=ref_positions,
        reference_note=(
            f"converged event-driven run (solve_ivp DOP853, rtol = atol = {ref_tol:g}, dense output); "
            f"its error is below its difference to the run at {100 * ref_tol:g} and half its largest step: "
            f"{estimate:.2e}"
        ),
        runs=runs,
        targets=targets_for(name, quick),
        reference_execution=reference,
        info={"reference_error_estimate": estimate},
        # rho is off by default here: the metric's projections onto these nonlinear guards
        # (SLSQP) cost about 0.4 s per sample time; --rho-points asks for it.
        rho_points=0,
    )


def _robot_model(name: str, quick: bool) -> tuple[Any, tuple[int, ...], float, str]:
    """The robot case's model, the state indices whose error is measured, t_final (s) and its
    description."""
    # Through the builder registry, as scenes find robots: the core never imports legsim.robots.
    try:
        builder = get_builder("pronk" if name == "pronk" else "double_pendulum")
    except LegsimError as exc:
        raise BenchError(
            f"case {name}: the robot model cannot be loaded ({exc}); install pinocchio (`pip install pin`)"
        ) from exc
    if name == "pronk":
        t_final = 0.5 if quick else 2.0
        description = f"pronking runner of paper 000 Sec. V-C (two hops, t in [0, {t_final}] s)"
        return builder.make(), (0, 1, 2), t_final, description
    model = builder.make(None, {"gravity": True, "stop": {"restitution": 0.0, "position": 0.0}})
    # Impact, constrained swing, release, graze, second impact and release; the event-driven
    # baseline meets a Zeno chatter at t = 7.38 s.
    t_final = 1.0 if quick else 5.0
    description = (
        f"double pendulum with a plastic stop, paper 003 Fig. 2b (impact, constrained swing, "
        f"release; t in [0, {t_final}] s)"
    )
    return model, (0, 1), t_final, description


def _robot_reference(name: str, system: Any, x0: np.ndarray, mode: str, t_final: float, positions: tuple[int, ...],
                     ref_tol: float) -> tuple[Any, Callable[[np.ndarray], np.ndarray], float]:  # fmt: skip
    """The converged event-driven reference (DOP853 at ``ref_tol``), its positions at given
    times (shape (len(times), len(positions))), and an estimate of its error."""
    from ..baselines import simulate_events

    def dop853(tol: float, max_step: float) -> Any:
        # A bounded step: solve_ivp cannot reject a trial step whose state leaves the model's range.
        return simulate_events(system, x0, mode, t_final, method="DOP853", rtol=tol, atol=tol, dense_output=True,
                               max_step=max_step)  # fmt: skip

    reference = dop853(ref_tol, 0.02)
    # The check differs in its steps as well as its tolerance: where the largest step binds, a
    # looser tolerance alone takes the very same steps, and the difference would be 0.
    check = dop853(100 * ref_tol, 0.01)
    if reference.status != "finished" or check.status != "finished":
        raise BenchError(f"case {name}: the reference run did not finish ({reference.status}: {reference.message})")

    def ref_positions(times: np.ndarray) -> np.ndarray:
        samples = reference.sample(np.clip(times, 0.0, reference.t_end))
        return np.array([s[list(positions)] for s in samples.states])

    grid = np.linspace(0.0, t_final, 4001)
    diff = ref_positions(grid) - np.array([s[list(positions)] for s in check.sample(grid).states])
    return reference, ref_positions, float(np.abs(diff).max())


def make_case(name: str, quick: bool = False) -> Case:
    """The case called ``name`` (one of ``CASE_NAMES``); ``quick`` shortens the run and the sweep."""
    if name == "oscillator-ex1":
        return _oscillator("ex1", quick)
    if name == "oscillator-ex2":
        return _oscillator("ex2", quick)
    if name == "bouncing-ball":
        return _bouncing_ball(quick)
    if name in ("pronk", "double-pendulum"):
        return _robot(name, quick)
    raise BenchError(f"unknown case {name!r}; choose one of {', '.join(CASE_NAMES)}")
