"""Issue 16, "crafted files": a saved execution, a recording or a scene with damaged or
hostile content is refused with an error naming the file and what is wrong (exit 2 on the
command line), never a raw exception, a wrapped-around index or an allocation the file's size
does not justify.

The damaged files are valid archives and recordings whose content was changed after writing,
as someone crafting one would."""

from __future__ import annotations

import json
import math
import re
import tracemalloc
import zipfile

import numpy as np
import pytest

from helpers.recordings import run_hopper
from helpers.reliability import npz_arrays, recording_with_meta, run_cli, write_ball, write_npz
from legsim import load_execution, save_execution
from legsim.errors import SimulationError

DEEP_JSON = "[" * 100_000 + "]" * 100_000


@pytest.fixture(scope="module")
def hopper():
    """(model, execution) of the hopper: modes of two dimensions, several transitions."""
    return run_hopper(t_final=1.0)


@pytest.fixture(scope="module")
def saved(hopper, tmp_path_factory):
    path = save_execution(hopper[1], tmp_path_factory.mktemp("saved") / "hopper.npz")
    return path, npz_arrays(path)


def damaged(arrays, change):
    """A copy of ``arrays`` (meta deep-copied) with ``change(copy)`` applied, and the meta text
    ``change`` returned (None: the copy's meta)."""
    copy = {k: (v.copy() if isinstance(v, np.ndarray) else json.loads(json.dumps(v))) for k, v in arrays.items()}
    text = change(copy)
    return copy, text if isinstance(text, str) else None


def _set(key, index, value):
    def change(a):
        a[key][index] = value

    return change


def _meta(update):
    def change(a):
        update(a["meta"])

    return change


# -- 6. load_execution -------------------------------------------------------------------------------
DAMAGE = {
    "an array missing": (lambda a: a.pop("seg_x") is None, r"arrays missing \['seg_x'\]"),
    "meta without modes": (_meta(lambda m: m.pop("modes")), r"meta lacks \['modes'\]"),
    "meta a list": (lambda a: "[1, 2]", "meta is an array, expected an object"),
    "a segment longer than the times": (_set("seg_len", 0, 10**6), "seg_t holds"),
    "states one value short": (lambda a: a.update(seg_x=a["seg_x"][:-1]) or None, "seg_x holds"),
    "a negative mode index": (_set("seg_mode", -1, -1), r"seg_mode\[\d+\] = -1 is not an index"),
    "a negative segment length": (_set("seg_len", 0, -3), r"seg_len\[0\] < 1"),
    "a dimension the mode has not": (_set("seg_dim", 0, 7), r"seg_dim\[0\] = 7, but mode 'flight' has 2"),
    "a NaN time": (_set("seg_t", 5, math.nan), "seg_t holds times that are not finite"),
    "times out of order": (_set("seg_t", 5, -1.0), "times of segment 0 do not increase"),
    "an inf state": (_set("seg_x", 3, math.inf), "seg_x holds values that are not finite"),
    "a negative strip mode": (_set("strip_mode", 0, -1), r"strip_mode\[0\] = -1"),
    "a transition to the wrong mode": (_set("tr_edge", (0, 1), 0), "does not match|does not join"),
    "names swapped": (_meta(lambda m: m["tr_names"].reverse()), "does not join"),
    "a NaN in meta": (lambda a: json.dumps({**a["meta"], "t_end": "NAN"}).replace('"NAN"', "NaN"), "NaN is not a JSON"),
    "meta nested 100,000 deep": (lambda a: DEEP_JSON, "nested more than 64 levels"),
    "an unknown status": (_meta(lambda m: m.update(status="exploded")), "meta.status 'exploded' is not one of"),
    "final_in_strip contradicting the strips": (_meta(lambda m: m.update(final_in_strip=True)), "final_in_strip"),
    "float indices": (
        lambda a: a.update(seg_mode=a["seg_mode"].astype(float)) or None,
        "dtype float64, expected int64",
    ),
    "strip times of the wrong shape": (
        lambda a: a.update(strip_times=a["strip_times"].reshape(-1, 2)) or None,
        r"strip_times has shape \(\d+, 2\), expected \('N', 4\)",
    ),
    "an extra array": (lambda a: a.update(payload=np.zeros(3)) or None, r"unexpected arrays \['payload'\]"),
}


@pytest.mark.parametrize("case", sorted(DAMAGE))
def test_a_damaged_execution_file_is_refused_by_name(saved, tmp_path, case):
    _, arrays = saved
    change, message = DAMAGE[case]
    copy, text = damaged(arrays, change)
    path = write_npz(tmp_path / "damaged.npz", copy, text)
    with pytest.raises(SimulationError, match=rf"^{path}: damaged legsim execution file: .*({message})"):
        load_execution(path)


def test_the_undamaged_copy_loads_and_samples(saved, hopper, tmp_path):
    # The damage above is all that differs: the same arrays written back load, and sample as
    # the execution did.
    _, arrays = saved
    copy, _ = damaged(arrays, lambda a: None)
    loaded = load_execution(write_npz(tmp_path / "same.npz", copy))
    times = np.linspace(loaded.t0, loaded.t_end, 97)
    got, want = loaded.sample(times), hopper[1].sample(times)
    assert got.modes == want.modes and all(np.array_equal(a, b) for a, b in zip(got.states, want.states, strict=True))


def test_a_pickled_array_is_refused_without_unpickling(saved, tmp_path):
    _, arrays = saved
    copy, _ = damaged(arrays, lambda a: None)
    copy["seg_t"] = np.array([object()] * 3, dtype=object)  # numpy pickles object arrays
    path = write_npz(tmp_path / "pickled.npz", copy)
    with pytest.raises(SimulationError, match="seg_t has dtype object"):
        load_execution(path)


def zip_bomb(path, arrays, member: str, values: int):
    """A valid execution archive whose ``member`` holds ``values`` float64 zeros (which deflate
    a thousandfold), written in chunks so that making it takes no memory."""
    from numpy.lib import format as npy

    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name, value in arrays.items():
            if name != member:
                data = np.array(json.dumps(value)) if name == "meta" else value
                with archive.open(f"{name}.npy", "w") as fh:
                    npy.write_array(fh, data, allow_pickle=False)
        with archive.open(f"{member}.npy", "w", force_zip64=True) as fh:
            npy.write_array_header_1_0(fh, {"descr": "<f8", "fortran_order": False, "shape": (values,)})
            chunk = bytes(1 << 20)
            for _ in range(values * 8 // len(chunk)):
                fh.write(chunk)
    return path


def test_an_array_header_with_a_negative_length_is_refused(saved, tmp_path):
    from numpy.lib import format as npy

    _, arrays = saved
    path = tmp_path / "negative.npz"
    with zipfile.ZipFile(path, "w") as archive:
        for name, value in arrays.items():
            with archive.open(f"{name}.npy", "w") as fh:
                if name == "seg_t":
                    npy.write_array_header_1_0(fh, {"descr": "<f8", "fortran_order": False, "shape": (-5,)})
                else:
                    npy.write_array(fh, np.array(json.dumps(value)) if name == "meta" else value)
    with pytest.raises(SimulationError, match=r"seg_t has shape \(-5,\), expected \('N',\)"):
        load_execution(path)


def test_a_small_file_that_inflates_a_thousandfold_is_refused_before_allocating(saved, tmp_path):
    _, arrays = saved
    bomb = zip_bomb(tmp_path / "bomb.npz", arrays, "seg_dx", 16 << 20)  # 128 MiB of zeros
    assert bomb.stat().st_size < 1 << 20
    tracemalloc.start()
    try:
        with pytest.raises(SimulationError, match=r"would take \d+ bytes decompressed, more than the \d+ allowed"):
            load_execution(bomb)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 16 << 20, f"{peak / 2**20:.0f} MiB allocated to refuse it"


# -- 7. legsim replay ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def meta(hopper, tmp_path_factory):
    """The legsim/meta document a recording of the hopper holds."""
    from legsim.output.rrd import read_rrd, write_rrd

    model, ex = hopper
    return read_rrd(write_rrd(ex, None, tmp_path_factory.mktemp("rrd") / "h.rrd", model=model))["meta"]


def _summary(update):
    def change(m):
        update(m["summary"])
        return json.dumps(m)

    return change


META_DAMAGE = {
    "summary without status": (_summary(lambda s: s.pop("status")), r"summary lacks \['status'\]"),
    "a time as text": (_summary(lambda s: s.update(t_final="1.0")), "summary.t_final is a string"),
    "a state as text": (_summary(lambda s: s["final_state"].__setitem__(0, "x")), r"summary.final_state\[0\]"),
    "nested 100,000 deep": (lambda m: DEEP_JSON, "nested more than 64 levels"),
    "meta a list": (lambda m: "[]", "unknown legsim recording format"),
    "modes not names": (lambda m: json.dumps({**m, "modes": [1, 2]}), r"legsim/meta.modes\[0\] is an integer"),
    "a NaN": (lambda m: json.dumps({**m, "t0": "NAN"}).replace('"NAN"', "NaN"), "NaN is not a JSON"),
    "an integer beyond float range": (_summary(lambda s: s.update(steps=10**400)), "summary.steps is an integer"),
    "a strip hold as a list": (
        _summary(lambda s: s.update(strip_time=0.1, longest_strip_hold=[])),
        "summary.longest_strip_hold is an array",
    ),
    "a warning without its message": (
        _summary(lambda s: s.update(warnings=[{"kind": "strip_hold"}])),
        r"summary.warnings\[0\] lacks",
    ),
}


@pytest.mark.parametrize("case", sorted(META_DAMAGE))
@pytest.mark.parametrize("mode", ["text", "--json"])
def test_replay_of_a_crafted_recording_is_a_clear_error(hopper, meta, tmp_path, case, mode):
    model, ex = hopper
    change, message = META_DAMAGE[case]
    path = recording_with_meta(tmp_path / "crafted.rrd", model, ex, change(json.loads(json.dumps(meta))))
    code, out, err = run_cli("replay", path, *([mode] if mode != "text" else []))
    assert code == 2 and out == "", err
    assert err.startswith(f"legsim: error: {path}: ") and err.count("\n") == 1
    assert re.search(message, err), err


# -- 8. deeply nested scenes ---------------------------------------------------------------------
NESTED = {
    "inline tables": "[robot.parameters]\nx = " + "{ a = " * 500 + "1" + " }" * 500 + "\n",
    "arrays": "[robot.parameters]\nx = " + "[" * 500 + "]" * 500 + "\n",
    "dotted keys": "[robot.parameters." + ".".join(["a"] * 500) + "]\nx = 1\n",
}


@pytest.mark.parametrize("kind", sorted(NESTED))
def test_a_scene_nested_500_deep_is_a_scene_error(tmp_path, kind):
    path = write_ball(tmp_path).with_name("deep.toml")
    path.write_text(NESTED[kind])
    code, out, err = run_cli("run", path)
    assert (code, out) == (2, "")
    assert err == f"legsim: error: {path}: nested more than 32 levels deep (tables and arrays)\n"


def test_one_bad_file_in_the_scene_path_is_listed_not_fatal(tmp_path, monkeypatch):
    write_ball(tmp_path, "good.toml")
    (tmp_path / "deep.toml").write_text(NESTED["inline tables"])
    (tmp_path / "huge.toml").write_text("# padding\n" * 200_000)
    monkeypatch.setenv("LEGSIM_SCENE_PATH", str(tmp_path))
    code, out, err = run_cli("scenes")
    lines = {line.split()[0]: line for line in out.splitlines()}
    # Exit 2 says that an entry is invalid; every scene is still listed.
    assert code == 2 and err == "" and "bouncing_ball" in lines
    assert "Bouncing ball" in lines["good"]
    assert "INVALID" in lines["deep"] and "nested more than 32 levels deep" in lines["deep"]
    assert "INVALID" in lines["huge"] and "larger than 1048576 bytes" in lines["huge"]
    code, out, _ = run_cli("scenes", "--json")
    rows = {r["name"]: r for r in json.loads(out)}
    assert code == 2 and "error" not in rows["good"] and "nested" in rows["deep"]["error"]
