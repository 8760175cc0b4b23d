"""The execution's assembly from the loop's records (legsim/relaxed/assemble.py): its objects
are made with Python's cyclic garbage collector paused, and the collector's state is the
caller's again afterwards."""

import gc

import numpy as np
import pytest

from legsim.methods import RK4
from legsim.relaxed import simulate
from legsim.systems import oscillator as osc
from legsim.systems.oscillator import EXAMPLES


def _chattering_run():
    """Example 2 of paper 000's Table I without the Zeno continuation: thousands of
    transitions through the sticking phases, each a strip and a transition record."""
    p = EXAMPLES["ex2"]
    system = osc.make_system(p["omega"], p["a"], p["x_max"], p["c"], p["mass"])
    control = osc.forcing(p["amplitude"], p["frequency"])
    x0 = np.array([p["x0"], p["xd0"]])
    return simulate(system, x0, "free", float(p["t_max"]), 1e-3, 1e-6, RK4, control, max_transitions=20_000,
                    continuation=False)  # fmt: skip


@pytest.fixture
def collections():
    """The cyclic collections started while the test runs, by generation."""
    counts = {0: 0, 1: 0, 2: 0}

    def count(phase, info):
        if phase == "start":
            counts[info["generation"]] += 1

    _chattering_run()  # compiled code loaded, caches filled: the counted run is the steady one
    # The collector starts empty, so that what the test counts is the run's own doing: objects an
    # earlier test left pending (a worker that just compiled a kernel holds millions) would set
    # off a full collection at the run's first young one, whatever the assembly does.
    gc.collect()
    gc.callbacks.append(count)
    yield counts
    gc.callbacks.remove(count)


def test_thousands_of_records_set_off_almost_no_cyclic_collection(collections):
    """7,448 transitions make about 15,000 records and 22,000 small objects: with the collector
    on through their assembly they set off about a hundred collections, a full one among them
    (measured: 106 of the youngest generation, 10 of the middle one, 1 full), each full one
    walking numba's and Pinocchio's objects. Paused, only the loop's own Python work between
    its calls into the kernel counts (measured: 7 and 1, no full one)."""
    ex = _chattering_run()
    assert ex.status == "finished" and len(ex.transitions) > 5000
    assert collections[2] == 0
    assert collections[0] + collections[1] < 30, collections


@pytest.mark.parametrize("enabled", [True, False])
def test_the_collector_is_left_as_the_caller_had_it(enabled):
    was = gc.isenabled()
    try:
        gc.enable() if enabled else gc.disable()
        ex = _chattering_run()
        assert gc.isenabled() is enabled
        assert ex.status == "finished"
    finally:
        gc.enable() if was else gc.disable()
