"""Fuzzing controller parameters: the standing quadruped's ``[controller]`` section and the
robot parameters its controller reads (``actuated``) replaced by values of any type, shape and
range, run with ``legsim run`` in-process (0.02 s of simulated time, a watchdog for hangs).

Allowed: exit 0, 2 or 3 with no traceback, 2 with one ``legsim: error:`` line (those found at
loading name the scene file, a joint listed twice in ``actuated`` included). A run that went ahead (exit 0 or 3) must
have had parameters ``joint_pd`` can use: ``kp`` and ``kd`` finite numbers >= 0, ``targets``
empty or one finite number per actuated joint, ``gravity`` a boolean, ``hold`` a boolean, no
other key (else a "silent wrong result": a nan target ran until the field was not finite, text
was an internal error).

The short form runs in CI; the ``slow``-marked long form draws new inputs (``-m slow`` or
``LEGSIM_FULL=1``). Run without xdist to print the outcome counts (docs/reliability.md).
"""

from __future__ import annotations

import math
import tempfile
import tomllib
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from helpers.fuzz import SCALARS, VALUES, toml_dumps
from helpers.reliability import FULL, Hang, record, run_cli, watchdog
from legsim.scene import bundled_dir

BASE = tomllib.loads((bundled_dir() / "quadruped_stand.toml").read_text())
BASE["integrator"]["t_final"] = 0.02
URDF = (bundled_dir() / "quadruped.urdf").read_text()
HANG_SECONDS = 120
FUZZER = "controller parameters (legsim run)"
JOINTS = ["hind_hip", "hind_knee", "front_hip", "front_knee"]


def fuzz_settings(examples: int, long: bool) -> settings:
    return settings(
        max_examples=examples,
        deadline=None,
        derandomize=not long,
        # a failure of the random long form prints the blob that replays it (@reproduce_failure)
        print_blob=long,
        database=None,
        suppress_health_check=list(HealthCheck),
    )


NUMBERS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -1.0, 1e-300, 1e300, 60.0, 3.0, -0.0]),
    st.integers(-(2**63), 2**63 - 1),
)
TARGETS = st.one_of(
    st.lists(NUMBERS, min_size=0, max_size=6),
    st.lists(st.sampled_from([-0.5, 1.0, 0.5, -1.0]), min_size=4, max_size=4),
    st.lists(VALUES, max_size=5),
    VALUES,
    st.just([0.0] * 5000),
)


@st.composite
def controller_sections(draw) -> tuple[dict, object]:
    """(the [controller] table, robot.parameters.actuated or a marker to keep the scene's)."""
    parameters: dict = {}
    for key, values in (
        ("kp", st.one_of(NUMBERS, VALUES)),
        ("kd", st.one_of(NUMBERS, VALUES)),
        ("targets", TARGETS),
        ("gravity", st.one_of(st.booleans(), SCALARS)),
    ):
        if draw(st.booleans()):
            parameters[key] = draw(values)
    if draw(st.integers(0, 5)) == 0:
        parameters[draw(st.text(min_size=1, max_size=6))] = draw(VALUES)
    table = {"name": draw(st.sampled_from(["joint_pd"] * 6 + ["raibert_slip", "nobody", ""])), "parameters": parameters}
    if draw(st.integers(0, 3)) == 0:
        table["hold"] = draw(st.one_of(st.booleans(), SCALARS))
    if draw(st.integers(0, 5)) == 0:
        table["parameters"] = draw(VALUES)
    keep = object()
    actuated = draw(
        st.one_of(
            st.just(keep),
            st.just(keep),
            st.lists(st.sampled_from([*JOINTS, "root", "nobody"]), max_size=5),
            st.just(["all"]),
            VALUES,
        )
    )
    return table, (None if actuated is keep else actuated)


def finite_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value >= 0


def usable(table: dict, actuated) -> bool:
    """Whether joint_pd can run with ``table`` on the quadruped with ``actuated`` (None: the scene's four)."""
    parameters = table.get("parameters")
    if table.get("name") != "joint_pd" or not isinstance(parameters, dict):
        return False
    if set(parameters) - {"kp", "kd", "targets", "gravity"} or set(table) - {"name", "parameters", "hold"}:
        return False
    if "hold" in table and not isinstance(table["hold"], bool):
        return False
    if any(k in parameters and not finite_number(parameters[k]) for k in ("kp", "kd")):
        return False
    if "gravity" in parameters and not isinstance(parameters["gravity"], bool):
        return False
    joints = JOINTS if actuated is None else (JOINTS if actuated == ["all"] else actuated)
    targets = parameters.get("targets", [])
    return isinstance(targets, list) and (
        targets == []
        or (
            len(targets) == len(joints)
            and all(isinstance(t, (int, float)) and not isinstance(t, bool) and math.isfinite(t) for t in targets)
        )
    )


def check(case) -> None:
    table, actuated = case
    data = {key: (dict(value) if isinstance(value, dict) else value) for key, value in BASE.items()}
    data["robot"] = {"name": "urdf", "parameters": dict(BASE["robot"]["parameters"])}
    if actuated is not None:
        data["robot"]["parameters"]["actuated"] = actuated
    data["controller"] = table
    text = toml_dumps(data)
    with tempfile.TemporaryDirectory(prefix="legsim-fuzz-controller-") as folder:
        scene = Path(folder) / "stand.toml"
        scene.write_text(text, encoding="utf-8", errors="surrogatepass")
        (Path(folder) / "quadruped.urdf").write_text(URDF)
        outcome, detail = outcome_of(scene, table, actuated)
    record(FUZZER, outcome)
    assert outcome in ("ran (exit 0 or 3)", "clear errors (exit 2)"), f"{outcome}: {detail}\n--- scene:\n{text}"


def outcome_of(scene: Path, table: dict, actuated) -> tuple[str, str]:
    try:
        with watchdog(HANG_SECONDS):
            code, _, err = run_cli("run", scene, "--json")
    except Hang as exc:
        return "hangs", str(exc)
    if code not in (0, 2, 3) or "Traceback" in err or "internal error" in err:
        return "tracebacks", f"exit {code}: {err[-2000:]}"
    if code == 2:
        if not err.startswith("legsim: error: ") or err.count("\n") != 1:
            return "tracebacks", f"not one error line: {err[-2000:]}"
        return "clear errors (exit 2)", err
    if not usable(table, actuated):
        return "silent wrong results", f"exit {code} with parameters {table!r:.500} (actuated {actuated!r:.200})"
    return "ran (exit 0 or 3)", ""


@pytest.mark.skipif(FULL, reason="the long form runs instead")
@fuzz_settings(60, long=False)
@given(controller_sections())
def test_fuzzed_controller_parameters_end_cleanly(case):
    check(case)


@pytest.mark.slow
@fuzz_settings(1000, long=True)
@given(controller_sections())
def test_fuzzed_controller_parameters_end_cleanly_long(case):
    check(case)
