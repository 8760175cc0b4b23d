"""Fuzzing ``legsim run`` with scene files: random mutations of the bundled scenes.

Each input is a bundled scene changed in one of three ways: its TOML content edited (values of
any type replaced, keys removed or added, tables nested hundreds deep), its text edited
character by character, or given ``[output]`` paths (and output flags) aimed at everything a
scene must not touch: absolute paths, ``..``, a link out of the folder, a FIFO, the scene file
itself. It runs in a fresh folder::

    root/scene/        the scene, a FIFO, a link to root/outside  (the scene's outputs may go here)
    root/cli/          where the output flags point                (the user's own outputs)
    root/outside/      a precious PNG                               (must never change)

and must end with exit 0, 2 or 3 only; never a traceback; no file outside root/scene and
root/cli created, changed or removed; no temporary file left; exit 0 only for a run that
finished at the scene's t_final with a finite state (else a "silent wrong result").

The short form runs in CI; ``LEGSIM_FULL=1`` runs the long one. Run without xdist to print
the outcome counts (docs/reliability.md).
"""

from __future__ import annotations

import json
import math
import os
import tempfile
import tomllib
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from helpers.fuzz import VALUES, Nested, toml_dumps
from helpers.reliability import FULL, Hang, record, run_cli, snapshot, temporaries, watchdog
from legsim.scene import bundled_dir, load_scene

BASES = {
    name: (bundled_dir() / f"{name}.toml").read_text()
    for name in ("bouncing_ball", "digital_control", "two_tanks", "grazing")
}
#: Every run is bounded, so that a mutated t_final or h cannot make one take minutes.
STEP_BUDGET = "integrator.max_steps=20000"
HANG_SECONDS = 120

FUZZ = settings(
    max_examples=1500 if FULL else 50,
    deadline=None,
    derandomize=not FULL,
    database=None,
    suppress_health_check=list(HealthCheck),
)


# Paths aimed at what a scene must not touch; {root} is the fuzz folder, never the host's.
OUTPUT_PATHS = [
    "out/x.png",
    "out/x.rrd",
    "out/x.html",
    "sub/dir/x.svg",
    "x.pdf",
    "{root}/outside/holiday.png",
    "{root}/outside/new.rrd",
    "../outside/holiday.png",
    "../outside/new.html",
    "out/../../outside/holiday.png",
    "shortcut/holiday.png",
    "shortcut/new.rrd",
    "fifo.png",
    "scene.rrd",
    "./scene.rrd",
    "",
    " ",
    ".",
    "..",
    "out/",
    "x\x00.png",
    "x.toml",
    "out/x.png/y.png",
]
CLI_PATHS = ["cli/a.rrd", "cli/a.html", "cli/a.png", "scene/scene.rrd", "scene/fifo.png", "cli", "cli/x.toml"]


#: Paths a scene may use, for the runs that go on to write their outputs.
GOOD_PATHS = {"rrd": "out/run.rrd", "html": "out/run.html", "plot": "out/run.png"}


def outputs_value(draw) -> dict:
    kinds = draw(
        st.lists(
            st.sampled_from(["rrd", "html", "plot", "rrd", "html", "plot", "movie"]),
            min_size=1,
            max_size=3,
            unique=True,
        )
    )
    return {kind: draw(st.sampled_from(OUTPUT_PATHS + [GOOD_PATHS.get(kind, "x")] * 8)) for kind in kinds}


def numbers(data: dict, prefix=()) -> list[tuple]:
    """Key paths of the numbers in ``data``."""
    out = []
    for key, value in data.items():
        if isinstance(value, dict):
            out += numbers(value, (*prefix, key))
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            out.append((*prefix, key))
    return out


def edit_number(draw, data: dict) -> None:
    """One number of ``data`` scaled, negated, zeroed, made tiny, huge or nan."""
    path = draw(st.sampled_from(numbers(data)))
    parent = data
    for key in path[:-1]:
        parent = parent[key]
    old = parent[path[-1]]
    factor = draw(st.sampled_from([0.5, 2.0, 10.0, 0.1, -1.0, 0.0, 1e-9, 1e9, math.nan, math.inf, 1.0000001]))
    parent[path[-1]] = (
        type(old)(old * factor) if isinstance(old, int) and math.isfinite(old * factor) else float(old) * factor
    )


def key_paths(data: dict, prefix=()) -> list[tuple]:
    out = []
    for key, value in data.items():
        out.append((*prefix, key))
        if isinstance(value, dict):
            out += key_paths(value, (*prefix, key))
    return out


def edit_structure(draw, data: dict) -> None:
    """Replace, remove or add one value somewhere in ``data``."""
    paths = key_paths(data)
    path = draw(st.sampled_from([*paths, ("integrator", "new_key"), ("new_section",), ("effects", "floor", "x")]))
    parent = data
    for key in path[:-1]:
        if not isinstance(parent.get(key), dict):
            parent[key] = {}
        parent = parent[key]
    action = draw(st.sampled_from(["replace", "replace", "remove", "nest"]))
    if path[0] == "output":
        # Output paths only from the list above, so that a fault can only touch the fuzz folder.
        parent[path[-1]] = outputs_value(draw) if len(path) == 1 else draw(st.sampled_from(OUTPUT_PATHS))
    elif action == "remove":
        parent.pop(path[-1], None)
    elif action == "nest":
        parent[path[-1]] = Nested(draw(st.integers(20, 600)), draw(st.booleans()))
    else:
        parent[path[-1]] = draw(VALUES)


def edit_text(draw, text: str) -> str:
    """One character-level edit: insert, delete, duplicate a line, or cut the file short."""
    action = draw(st.sampled_from(["insert", "delete", "duplicate", "truncate"]))
    at = draw(st.integers(0, len(text)))
    if action == "insert":
        return text[:at] + draw(st.text(min_size=1, max_size=4)) + text[at:]
    if action == "delete":
        return text[:at] + text[at + draw(st.integers(1, 20)) :]
    lines = text.splitlines(keepends=True)
    if action == "duplicate" and lines:
        k = draw(st.integers(0, len(lines) - 1))
        return "".join(lines[: k + 1] + lines[k:])
    return text[:at] if action == "truncate" else text


@st.composite
def scene_inputs(draw):
    """(scene text, file name, extra command-line flags)."""
    base = BASES[draw(st.sampled_from(sorted(BASES)))]
    how = draw(st.sampled_from(["structure", "text", "outputs", "numbers", "numbers"]))
    if how == "text":
        text = base
        for _ in range(draw(st.integers(1, 5))):
            text = edit_text(draw, text)
    else:
        data = tomllib.loads(base)
        if how == "outputs":
            data["output"] = outputs_value(draw)
        if how == "numbers":
            for _ in range(draw(st.integers(1, 3))):
                edit_number(draw, data)
        for _ in range(draw(st.integers(1 if how == "structure" else 0, 4 if how == "structure" else 1))):
            edit_structure(draw, data)
        text = toml_dumps(data)
    flags = []
    for kind in draw(st.lists(st.sampled_from(["rrd", "html", "plot"]), max_size=2, unique=True)):
        good = f"cli/b.{dict(rrd='rrd', html='html', plot='png')[kind]}"
        flags += [f"--{kind}", draw(st.sampled_from(CLI_PATHS + [good] * 6))]
    return text, draw(st.sampled_from(["scene.toml", "scene.rrd"])), flags


# -- one input -----------------------------------------------------------------------------------
def make_world(root: Path, text: str, name: str) -> Path:
    """The folders of the module docstring; returns the scene file."""
    scene, outside = root / "scene", root / "outside"
    for folder in (scene, outside, root / "cli"):
        folder.mkdir()
    (outside / "holiday.png").write_bytes(b"\x89PNG precious")
    os.mkfifo(scene / "fifo.png")
    os.symlink(outside, scene / "shortcut")
    path = scene / name
    path.write_text(text.replace("{root}", str(root)), encoding="utf-8", errors="surrogatepass")
    return path


def outcome_of(root: Path, path: Path, flags: list[str]) -> tuple[str, str]:
    """(outcome, detail) of ``legsim run`` on the scene at ``path``."""
    guarded = {k: v for k, v in snapshot(root).items() if not k.startswith(("scene", "cli"))}
    argv = ["run", path, "--json", "--set", STEP_BUDGET] + [f if f.startswith("--") else root / f for f in flags]
    try:
        with watchdog(HANG_SECONDS):
            code, out, err = run_cli(*argv)
    except Hang as exc:
        return "hangs", str(exc)
    if (
        code not in (0, 2, 3)
        or "Traceback" in err
        or "internal error" in err
        or (code == 2 and not err.startswith("legsim: error: "))
    ):
        return "tracebacks", f"exit {code}: {err[-2000:]}"
    if {k: v for k, v in snapshot(root).items() if not k.startswith(("scene", "cli"))} != guarded:
        return "files lost or changed", err
    if temporaries(root):
        return "temporaries left", str(temporaries(root))
    if code == 2:
        return "clear errors (exit 2)", err
    return check_run(path, code, out)


def check_run(path: Path, code: int, out: str) -> tuple[str, str]:
    """A run's summary against its scene: exit 0 is a finished run at t_final, finite state."""
    summary = json.loads(out)
    finished = summary["status"] == "finished"
    if finished != (code == 0):
        return "silent wrong results", f"exit {code} with status {summary['status']}"
    if finished:
        wanted = load_scene(path, [STEP_BUDGET]).integrator["t_final"]
        if summary["t_final"] != wanted or any(v is None for v in summary["final_state"]):
            return "silent wrong results", f"finished at {summary['t_final']} of {wanted}: {summary['final_state']}"
    for target in summary.get("outputs", {}).values():
        if not Path(target).is_file():
            return "silent wrong results", f"output {target} reported but absent"
    return "ran (exit 0 or 3)", ""


@FUZZ
@given(scene_inputs())
def test_fuzzed_scenes_end_cleanly(case):
    text, name, flags = case
    with tempfile.TemporaryDirectory(prefix="legsim-fuzz-") as folder:
        root = Path(folder)
        path = make_world(root, text, name)
        outcome, detail = outcome_of(root, path, flags)
    record("scene files (legsim run)", outcome)
    assert outcome in ("ran (exit 0 or 3)", "clear errors (exit 2)"), f"{outcome}: {detail}\n--- scene:\n{text}"
