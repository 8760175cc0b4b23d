"""A scene's ``[integrator]`` table, validated: the settings of ``legsim.relaxed.simulate`` with
their defaults, ranges and the checks between them (error control needs an embedded pair,
dense landing a continuous extension, the step budget and float spacing of t). The orbit
search's ``[orbit.integrator]`` is checked the same way, named by its own path."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..builders import Param, resolve_parameters
from ..relaxed.simulate import MAX_STEPS as SIMULATE_MAX_STEPS
from .fields import field_error

REQUIRED_INTEGRATOR = ("t_final", "h", "eps")

# The integrator's step budget (legsim.relaxed.simulate.MAX_STEPS): an absurd t_final or h is
# refused at loading instead of filling memory for hours; a scene that means it raises
# integrator.max_steps.
MAX_STEPS = SIMULATE_MAX_STEPS


def _integrator_schema() -> dict[str, Param]:
    from ..methods import ALIASES, METHODS
    from ..methods.builtin import SCIPY_NAMES

    # scipy's spellings mean what they mean to simulate: error control, with solve_ivp's default
    # tolerances unless rtol or atol is given.
    methods = tuple(sorted(METHODS) + sorted(ALIASES)) + SCIPY_NAMES
    return {
        "method": Param("rk4", "Runge-Kutta method", choices=methods),
        "h": Param(1e-3, "nominal step size", "s", low=0.0, low_open=True),
        "eps": Param(1e-3, "strip width", "guard units", low=0.0, low_open=True),
        "t_final": Param(1.0, "end time", "s", low=0.0, low_open=True),
        "t0": Param(0.0, "start time", "s"),
        "max_transitions": Param(100_000, "transition budget", low=0),
        "max_halvings": Param(64, "most halvings of one step", low=1),
        "max_steps": Param(MAX_STEPS, "most nominal steps (t_final - t0) / h a run may take", low=1),
        "landing": Param("halve", "how a step past the strip is shortened", choices=("halve", "aim", "dense")),
        "continuation": Param(True, "take a transition's continuation when its crossings accumulate (Zeno)"),
        # Optional error control (no default: absent means fixed nominal steps).
        "rtol": Param(1e-6, "relative tolerance of error-controlled steps", low=0.0, low_open=True),
        "atol": Param(1e-9, "absolute tolerance of error-controlled steps", low=0.0, low_open=True),
        "zeno_window": Param(
            2e-3,
            "shortest flight resolved before crossings count as accumulating (default h + eps)",
            "s",
            low=0.0,
            low_open=True,
        ),
    }


OPTIONAL_INTEGRATOR = ("rtol", "atol", "zeno_window")


def validated_integrator(path: Path, table: dict[str, Any], where: str = "integrator") -> dict[str, Any]:
    """The validated ``[integrator]`` table (``where``: the name its fields are reported by)."""
    schema = _integrator_schema()
    missing = [key for key in REQUIRED_INTEGRATOR if key not in table]
    if missing:
        raise field_error(
            path,
            f"{where}.{missing[0]}",
            f"missing; a scene must give {list(REQUIRED_INTEGRATOR)} "
            f"({', '.join(f'{k}: {schema[k].allowed_with_unit()}' for k in missing)})",
        )
    out = resolve_parameters(schema, table, f"{path}: {where}")
    for key in OPTIONAL_INTEGRATOR:
        if key not in table:
            out[key] = None
    if out["rtol"] is not None or out["atol"] is not None:
        from ..methods import get_method

        if not get_method(out["method"]).embedded:
            key = "rtol" if out["rtol"] is not None else "atol"
            raise field_error(
                path,
                f"{where}.{key}",
                f"error control needs a method with an embedded error "
                f"estimate (method = 'bs32', 'dopri5', 'dop853' or 'ros34pw2'), got "
                f"method = '{out['method']}'",
            )
    if out["landing"] == "dense":
        from ..methods import dense_output, get_method

        if dense_output(get_method(out["method"])) is None:
            raise field_error(
                path,
                f"{where}.landing",
                f"'dense' lands on the method's continuous extension, which "
                f"method = '{out['method']}' has not (bs32, dopri5 and dop853 "
                f"have one); use landing = 'aim'",
            )
    if out["t_final"] <= out["t0"]:
        raise field_error(path, f"{where}.t_final", f"{out['t_final']!r} must be > {where}.t0 = {out['t0']!r}")
    _check_step_fits(path, out, where)
    nominal = (out["t_final"] - out["t0"]) / out["h"]
    if nominal > out["max_steps"]:
        raise field_error(
            path,
            f"{where}.max_steps",
            f"t_final - t0 = {out['t_final'] - out['t0']:g} s at h = {out['h']:g} s is {nominal:.3g} steps, "
            f"more than max_steps = {out['max_steps']}; every step is stored, so check t_final and h, "
            f"or raise {where}.max_steps if the run is meant to be that long",
        )
    # Far from t = 0 the spacing of float64 times can exceed h: t + h == t, and the integrator
    # would make no progress (or no halving could land). Ask for h to be resolved to a
    # millionth (2^20 spacings), which leaves room for the halvings of a landing.
    spacing = float(np.spacing(max(abs(out["t0"]), abs(out["t_final"]))))
    if out["h"] < 2.0**20 * spacing:
        raise field_error(
            path,
            f"{where}.h",
            f"{out['h']:g} s is too small for times near "
            f"{max(abs(out['t0']), abs(out['t_final'])):g} s, where float64 "
            f"times are {spacing:.3g} s apart; h must be >= {2.0**20 * spacing:.3g} s "
            f"(2^20 spacings), or shift t0 and t_final towards 0",
        )
    return out


#: Key of ``Model.info`` under which a model whose fields jump inside a mode, where no guard lands
#: a step, says why fixed steps cannot be vouched for there (a string): its scenes then need
#: error-controlled steps.
NEEDS_ERROR_CONTROL = "needs_error_control"


def fixed_steps(settings: Mapping[str, Any]) -> bool:
    """Whether an ``[integrator]`` table's run takes fixed steps: no rtol or atol, and not one of
    scipy's method names (which imply error control)."""
    from ..methods.builtin import SCIPY_NAMES

    return settings["rtol"] is None and settings["atol"] is None and settings["method"] not in SCIPY_NAMES


def check_step_rule(
    path: Path, info: Mapping[str, Any], settings: Mapping[str, Any], where: str = "integrator"
) -> None:
    """Refuse fixed steps for a model that needs error control (``NEEDS_ERROR_CONTROL`` in its
    ``info``, ``Model.info``), naming the field to set and the model's reason."""
    reason = info.get(NEEDS_ERROR_CONTROL)
    if reason and fixed_steps(settings):
        raise field_error(
            path,
            f"{where}.rtol",
            f"missing: fixed steps (method {settings['method']!r}, no rtol or atol) cannot be vouched for here: "
            f"{reason}; give rtol (and atol) with an embedded method (bs32, dopri5, dop853)",
        )


def _check_step_fits(path: Path, out: dict[str, Any], where: str) -> None:
    """A fixed step longer than the run is refused: the run would be one step, resolving nothing
    of the motion (an error-controlled run takes h as its largest step, which may be long)."""
    fixed = fixed_steps(out)
    span = out["t_final"] - out["t0"]
    if fixed and out["h"] > span:
        raise field_error(
            path,
            f"{where}.h",
            f"{out['h']:g} s is longer than the run (t_final - t0 = {span:g} s): with fixed steps it would be "
            f"one step; give h well below the time scale of the motion (or rtol/atol for error-controlled steps, "
            f"where h is the largest step)",
        )
