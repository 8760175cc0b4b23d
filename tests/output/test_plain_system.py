"""The writers take a plain ``HybridSystem`` as ``model=``, as docs/recording.md says: the
recording, the plot and the summary of a run of docs/method.md's ball without a scene or a
``Model``; the animation, which needs geometry, says that it has none."""

from __future__ import annotations

import numpy as np
import pytest

from legsim import HybridSystem, Mode, Transition, simulate
from legsim.errors import OutputError
from legsim.output.summary import run_summary
from legsim.record import read_rrd, write_rrd

G, C = 9.81, 0.5


@pytest.fixture(scope="module")
def ball_run():
    ball = HybridSystem(
        {"flight": Mode(2, lambda t, x, u: np.array([x[1], -G]), names=("z", "zd"))},
        [
            Transition(
                "flight",
                "flight",
                guard=lambda x: max(x[0], x[1]),
                reset=lambda x: np.array([x[0], -C * x[1]]),
                name="bounce",
            )
        ],
        name="ball",
        energy=lambda mode, x: G * x[0] + 0.5 * x[1] ** 2,
    )
    return ball, simulate(ball, [1.0, 0.0], "flight", t_final=1.0, h=1e-3, eps=1e-3, method="rk4")


def test_a_recording_of_a_plain_system_holds_its_run_and_energy(ball_run, tmp_path):
    ball, ex = ball_run
    write_rrd(ex, None, tmp_path / "ball.rrd", model=ball)
    data = read_rrd(tmp_path / "ball.rrd")
    assert data["mode_sequence"] == ex.mode_sequence and data["transitions"][0]["name"] == "bounce"
    assert data["summary"]["energy_initial"] == pytest.approx(G * 1.0)
    assert data["summary"] == run_summary(ex, None, ball) and data["frames"] is None


def test_a_plot_of_a_plain_system(ball_run, tmp_path):
    from legsim.viz.plots import write_plot

    ball, ex = ball_run
    assert write_plot(ex, None, tmp_path / "ball.png", model=ball).stat().st_size > 0


def test_an_animation_of_a_plain_system_says_it_has_no_geometry(ball_run, tmp_path):
    from legsim.viz.meshcat_anim import write_html

    ball, ex = ball_run
    with pytest.raises(OutputError, match="an html animation needs the robot's geometry, and ball defines none"):
        write_html(ex, None, tmp_path / "ball.html", model=ball)
    assert not (tmp_path / "ball.html").exists()


def test_a_model_of_another_kind_is_named(ball_run, tmp_path):
    _, ex = ball_run
    with pytest.raises(
        OutputError, match=r"write_rrd: model= takes a legsim.builders.Model or a HybridSystem, got dict"
    ):
        write_rrd(ex, None, tmp_path / "x.rrd", model={"system": None})
