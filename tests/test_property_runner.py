"""Property-based: the pronking runner (paper 000 Sec. V-C) from random apexes, pitches and pitch
rates keeps the stress suite's invariants. It may fall (the passive runner is unstable), but then
with an honest status (model_breakdown, halving_exhausted), keeping a valid execution; energy is
conserved along the way and across every touchdown and liftoff; a leg touches down and lifts off
at most once per hop.

CI runs ten examples; LEGSIM_FULL=1 runs 100."""

import itertools
import os

from hypothesis import given, settings
from hypothesis import strategies as st

from legsim import simulate, stress

FULL = os.environ.get("LEGSIM_FULL") == "1"
SETTINGS = settings(max_examples=100 if FULL else 10, deadline=None, derandomize=not FULL)
MODEL = stress.build("pronk")
FALLS = ("finished", "model_breakdown", "halving_exhausted", "reset_outside_domain")


@SETTINGS
@given(
    z=st.floats(0.95, 1.4),
    xd=st.floats(2.0, 5.0),
    theta=st.floats(-0.1, 0.1),
    thetad=st.floats(-0.5, 0.5),
    eps=st.sampled_from([1e-4, 1e-3, 1e-2]),
)
def test_runner_keeps_the_invariants_and_its_energy(z, xd, theta, thetad, eps):
    system = MODEL.system
    x0 = stress._state(MODEL, "aerial", {"z": z, "xd": xd, "theta": theta, "thetad": thetad})
    h, T = 1e-3, 1.2
    ex = simulate(system, x0, "aerial", T, h, eps, max_transitions=100)
    # each aerial phase ends with at most two touchdowns and two liftoffs before the next one
    aerials = ex.mode_sequence.count("aerial")
    checks = stress.execution_checks(
        system, ex, eps, status=FALLS, energy="conservative", energy_tol=1e-6, bound=4 * aerials, bound_why="4 per hop"
    )
    assert all(ch.passed for ch in checks), [f"{ch.name}: {ch.detail}" for ch in checks if not ch.passed]
    for tr in ex.transitions:  # the feet are pinned and released at rest length: no energy jump
        assert abs(system.energy(tr.target, tr.state_after) - system.energy(tr.source, tr.state_before)) <= 1e-9
    if ex.status != "finished":
        assert ex.message and ex.t_end < T
    # the legs alternate touchdown and liftoff
    for leg in ("left", "right"):
        kinds = [tr.name.split("_")[0] for tr in ex.transitions if tr.name.endswith(leg)]
        assert all(a != b for a, b in itertools.pairwise(kinds)), kinds
