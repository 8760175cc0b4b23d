"""Optional: legsim's compiled quadruped stand against MuJoCo's, timed alternately.

MuJoCo is never installed into the project's venv, and legsim never imports it. Set it up once in
its own environment; this script starts that environment's Python on this same file
(``--worker``), which builds and runs the MuJoCo model and answers over a pipe, so the two
simulators run alternately, config by config, never at the same time:

    python3 -m venv /work/mujoco-venv && /work/mujoco-venv/bin/pip install mujoco
    .venv/bin/python benchmarks/mujoco_compare.py --mujoco-python /work/mujoco-venv/bin/python [--rounds 3] [--quick]

The robot is the planar quadruped of the scene ``quadruped_stand`` (``scenarios/quadruped.urdf``
on a planar root x, z, pitch; the joint PD ``u = kp (q* - q) - kd dq/dt + g(q)`` on the four leg
joints; point feet with friction 0.8; dropped from z = 0.6 m, both feet land at t = 0.18 s and
it stands). The MuJoCo model is written by this script from the URDF (``mjcf``): the same links,
inertials and joints in legsim's coordinate order, the root as slide x, slide z, hinge y; each
foot a sphere of radius ``FOOT_RADIUS`` over a floor lowered by that radius, so a foot touches
the floor where legsim's point foot does; friction 0.8 (the feet's: the floor's is 0, MuJoCo takes
the larger of the two), MuJoCo's default (soft) contact model
otherwise; the PD's spring and damper as an affine actuator bias, continuous inside MuJoCo's
step (and implicit in ``implicitfast``), ``kp q* + g(q)`` set as the control before every step,
with g(q) MuJoCo's own (``mj_rne`` at the step's position, zero velocity). The knee stops of the
scene are joint limits there; neither simulator reaches them in this run. Before comparing,
the mass matrices and g(q) of both (legsim's through Pinocchio, the bridge's model) are compared
at a few states; the script refuses to go on when they differ by more than 1e-9 relative.

What is compared is cost at equal accuracy, each simulator against ITS OWN converged reference:
the two contact models differ (legsim's feet are rigid, with an impact; MuJoCo's are soft), so
their trajectories differ by more than either's error, and neither is the other's reference.
The error of a run is the largest difference, over the sample times 0, 4 ms, ..., t_final, of
the seven plant coordinates (x, z in m; pitch and the joints in rad) from the reference run of
the same simulator (legsim: rk4, h = 2e-5, eps = 1e-9; MuJoCo: RK4, dt = 1e-5). legsim's states
at the sample times are its execution's interpolant (``t_eval``); MuJoCo's are its step ends
(dt up to 4 ms divides 4 ms; a run at dt = 8 ms is compared at its own steps, every other
sample). legsim's configurations: rk4 and ros34pw2 with fixed steps, dopri5 and ros34pw2 with
error control (largest step 20 ms; ros34pw2 at loose tolerances also 50 and 100 ms), at several
strip widths eps; MuJoCo's: Euler, implicitfast and RK4 at dt 0.5, 1, 2, 4 and 8 ms. Wall
times are per simulated second, each the best of ``--repeat`` runs, a legsim configuration and a
MuJoCo one taken in turn; per error level the
fastest run of each side that reaches it is taken, per round, and the median over rounds of
legsim / MuJoCo printed (< 1: legsim faster). legsim runs compiled (every run is checked to
have taken no Python step) and warm: its first run in a fresh process (loading the kernels from
the cache) and the scene's loading are reported separately, as are MuJoCo's model compile and
first run. Print ``uptime`` next to the numbers.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

SCENE = "quadruped_stand"
T_FINAL = 1.0
SAMPLE_DT = 4e-3
FOOT_RADIUS = 1e-3
LEVELS = (1e-1, 3e-2, 1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 1e-5, 1e-6)
MASS_TOLERANCE = 1e-9
LEGSIM_REFERENCE = ("rk4", 2e-5, 1e-9, None)
MUJOCO_REFERENCE = ("RK4", 1e-5)
DEFAULT_MUJOCO_PYTHON = "/work/mujoco-venv/bin/python"


# -- the MuJoCo model, written from the URDF (no MuJoCo needed) -----------------------------------


def _xyz(element, attribute: str = "xyz") -> list[float]:
    origin = element.find("origin") if element is not None else None
    if origin is None:
        return [0.0, 0.0, 0.0]
    if any(abs(float(v)) > 0.0 for v in origin.get("rpy", "0 0 0").split()):
        raise ValueError("mjcf: joint and inertial origins with a rotation (rpy) are not supported")
    return [float(v) for v in origin.get(attribute, "0 0 0").split()]


def _fmt(values) -> str:
    return " ".join(repr(float(v)) for v in values)


def mjcf(
    urdf: str | Path,
    order: tuple[str, ...],
    feet: dict[str, float],
    kp: float,
    kd: float,
    targets,
    actuated: tuple[str, ...],
    stops: dict[str, tuple[float, float]],
    radius: float = FOOT_RADIUS,
    integrator: str = "implicitfast",
    dt: float = 2e-3,
) -> str:
    """MJCF of a planar URDF robot: root slide x, slide z, hinge y on the URDF's root link, each
    revolute joint a hinge, fixed joints merged into their parent (a link named in ``feet`` gives a
    sphere of ``radius`` there with that friction), children in the order of ``order`` (legsim's
    coordinate names, so qpos has legsim's order), the floor at z = -radius. The PD is an affine
    actuator ``ctrl - kp q - kd dq/dt`` per actuated joint; ``stops`` are joint ranges."""
    root_el = ET.parse(urdf).getroot()
    links = {link.get("name"): link for link in root_el.findall("link")}
    joints = root_el.findall("joint")
    children: dict[str, list] = {}
    for joint in joints:
        children.setdefault(joint.find("parent").get("link"), []).append(joint)
    child_links = {j.find("child").get("link") for j in joints}
    (root_link,) = [name for name in links if name not in child_links]
    rank = {name: i for i, name in enumerate(order)}

    def first_rank(joint) -> int:
        if joint.get("type") != "fixed":
            return rank[joint.get("name")]
        nested = children.get(joint.find("child").get("link"), [])
        return min([first_rank(j) for j in nested], default=len(rank))

    def inertial(link) -> str:
        el = link.find("inertial")
        if el is None:
            return ""
        i = {k: float(el.find("inertia").get(k)) for k in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")}
        full = [i["ixx"], i["iyy"], i["izz"], i["ixy"], i["ixz"], i["iyz"]]
        return (
            f'<inertial pos="{_fmt(_xyz(el))}" mass="{float(el.find("mass").get("value"))!r}" '
            f'fullinertia="{_fmt(full)}"/>'
        )

    def body_content(link_name: str, offset: list[float]) -> str:
        link = links[link_name]
        parts = []
        if offset == [0.0, 0.0, 0.0]:
            parts.append(inertial(link))
        elif link.find("inertial") is not None:
            raise ValueError(f"mjcf: fixed-joint child link '{link_name}' with mass is not supported")
        if link_name in feet:
            parts.append(
                f'<geom name="{link_name}" type="sphere" size="{radius!r}" pos="{_fmt(offset)}" '
                f'friction="{feet[link_name]!r} 0 0" condim="3"/>'
            )
        for joint in sorted(children.get(link_name, []), key=first_rank):
            child = joint.find("child").get("link")
            pos = [a + b for a, b in zip(offset, _xyz(joint), strict=True)]
            if joint.get("type") == "fixed":
                parts.append(body_content(child, pos))
                continue
            if joint.get("type") not in ("revolute", "continuous"):
                raise ValueError(f"mjcf: joint type {joint.get('type')} is not supported")
            axis = joint.find("axis").get("xyz") if joint.find("axis") is not None else "1 0 0"
            name = joint.get("name")
            limit = f' range="{_fmt(stops[name])}"' if name in stops else ""
            parts.append(
                f'<body name="{child}" pos="{_fmt(pos)}"><joint name="{name}" type="hinge" '
                f'axis="{axis}"{limit}/>{body_content(child, [0.0, 0.0, 0.0])}</body>'
            )
        return "".join(parts)

    actuators = "".join(
        f'<general name="{name}" joint="{name}" gainprm="1" biastype="affine" biasprm="0 {-kp!r} {-kd!r}"/>'
        for name in actuated
    )
    return (
        f'<mujoco model="{root_el.get("name")}"><compiler angle="radian" inertiafromgeom="false" '
        f'autolimits="true"/><option timestep="{dt!r}" integrator="{integrator}" gravity="0 0 -9.81"/>'
        f'<worldbody><geom name="floor" type="plane" size="0 0 1" pos="0 0 {-radius!r}" friction="0 0 0"/>'
        f'<body name="{root_link}"><joint name="x" type="slide" axis="1 0 0"/>'
        f'<joint name="z" type="slide" axis="0 0 1"/><joint name="pitch" type="hinge" axis="0 1 0"/>'
        f"{body_content(root_link, [0.0, 0.0, 0.0])}</body></worldbody><actuator>{actuators}</actuator></mujoco>"
    )


# -- the MuJoCo side: runs in MuJoCo's venv (``--worker``), answers JSON lines -------------------


class MujocoSide:
    def __init__(self, xml: str, q0: list[float], targets: list[float], kp: float, actuated_dofs: list[int]):
        import mujoco

        self.mj = mujoco
        start = time.perf_counter()
        self.model = mujoco.MjModel.from_xml_string(xml)
        self.compile_s = time.perf_counter() - start
        self.xml, self.q0 = xml, np.array(q0)
        self.dofs = np.array(actuated_dofs)
        if not np.array_equal(self.dofs, np.arange(self.dofs[0], self.dofs[0] + len(self.dofs))):
            raise ValueError(f"the actuated dofs {actuated_dofs} must be contiguous and increasing")
        self.bias = kp * np.array(targets)
        self.gravity = True

    def names(self) -> list[str]:
        return [self.model.joint(i).name for i in range(self.model.njnt)]

    def dynamics(self, q) -> dict:
        """Mass matrix and g(q) (``mj_rne`` at zero velocity) at position q."""
        m, mj = self.model, self.mj
        d = mj.MjData(m)
        d.qpos[:] = q
        mj.mj_forward(m, d)
        full = np.zeros((m.nv, m.nv))
        mj.mj_fullM(m, d, full)
        g = np.zeros(m.nv)
        mj.mj_rne(m, d, 0, g)
        return {"M": full.tolist(), "g": g.tolist()}

    def run(self, integrator: str, dt: float, t_final: float, every: int, repeat: int, gravity: bool = True) -> dict:
        """Best wall time of ``repeat`` runs (s), and the positions at every ``every``-th step
        (``gravity`` False: g(q) left out, to time MuJoCo's step alone; not the same robot)."""
        mj = self.mj
        self.gravity = gravity
        m = self.model
        m.opt.timestep = dt
        m.opt.integrator = getattr(mj.mjtIntegrator, f"mjINT_{integrator.upper()}")
        steps = round(t_final / dt)
        walls, samples = [], []
        for k in range(repeat + 1):
            record = k == repeat  # the positions come from one untimed run after the timed ones
            d, g_data = mj.MjData(m), mj.MjData(m)
            d.qpos[:] = self.q0
            g, bias, ctrl, qpos, g_qpos = np.zeros(m.nv), self.bias, d.ctrl, d.qpos, g_data.qpos
            g_act = g[self.dofs[0] : self.dofs[-1] + 1]  # the actuated dofs are contiguous (checked on load)
            kinematics, com_pos, rne, step, add = mj.mj_kinematics, mj.mj_comPos, mj.mj_rne, mj.mj_step, np.add
            start = time.perf_counter()
            for i in range(steps):
                if record and i % every == 0:
                    samples.append(qpos.tolist())
                if self.gravity:
                    g_qpos[:] = qpos  # g(q) at the step's start, zero velocity (g_data.cvel stays 0)
                    kinematics(m, g_data)
                    com_pos(m, g_data)
                    rne(m, g_data, 0, g)
                add(bias, g_act, out=ctrl)
                step(m, d)
            if record:
                samples.append(qpos.tolist())
            else:
                walls.append(time.perf_counter() - start)
        # MuJoCo resets a run whose accelerations blow up to its initial state and goes on: such a run diverged.
        unstable = int(sum(d.warning[w].number for w in (mj.mjtWarning.mjWARN_BADQACC, mj.mjtWarning.mjWARN_BADQVEL)))
        return {"wall": min(walls) if walls else math.nan, "q": samples, "unstable": unstable > 0}


def serve() -> int:
    import mujoco

    mujoco.set_mju_user_warning(lambda text: None)  # a diverged run is reported in the reply ("unstable")
    side = None
    for line in sys.stdin:
        request = json.loads(line)
        kind = request.pop("cmd")
        if kind == "load":
            side = MujocoSide(**request)
            reply = {"names": side.names(), "compile_s": side.compile_s, "version": mujoco.__version__}
        elif kind == "dynamics":
            reply = side.dynamics(request["q"])
        elif kind == "run":
            reply = side.run(**request)
        else:
            reply = {"error": f"unknown command {kind}"}
        sys.stdout.write(json.dumps(reply) + "\n")
        sys.stdout.flush()
    return 0


class Worker:
    """MuJoCo's side, in its own Python (``--mujoco-python``), over a pipe."""

    def __init__(self, python: str) -> None:
        self.proc = subprocess.Popen(
            [python, os.path.abspath(__file__), "--worker"], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
        )

    def ask(self, cmd: str, **request) -> dict:
        self.proc.stdin.write(json.dumps({"cmd": cmd, **request}) + "\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError("the MuJoCo worker ended (see its error above)")
        reply = json.loads(line)
        if "error" in reply:
            raise RuntimeError(reply["error"])
        return reply

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait(timeout=30)


# -- the legsim side ------------------------------------------------------------------------------


class LegsimSide:
    def __init__(self, t_final: float) -> None:
        start = time.perf_counter()
        from legsim.scene import load_scene

        self.scene = load_scene(SCENE)
        self.load_s = time.perf_counter() - start
        self.t_final = t_final
        self.times = sample_times(t_final)
        start = time.perf_counter()
        self.run(("rk4", 1e-3, 1e-4, None))
        self.first_run_s = time.perf_counter() - start

    def run(self, config: tuple, record: bool = False):
        """(wall s, positions at the sample times or None when the run did not finish)."""
        from legsim.relaxed import simulate

        method, h, eps, rtol = config
        sc = self.scene
        start = time.perf_counter()
        ex = simulate(
            sc.model.system,
            sc.initial_state.copy(),
            sc.initial_mode,
            self.t_final,
            h,
            eps,
            method,
            sc.control,
            rtol=rtol,
            atol=rtol,
            t_eval=self.times if record else None,
        )
        wall = time.perf_counter() - start
        if ex.counters["python_steps"] != 0:
            raise RuntimeError(f"legsim {config} took {ex.counters['python_steps']} Python steps: not compiled")
        if ex.status != "finished":
            return wall, None
        return wall, (np.array(ex.evaluated.states)[:, :7] if record else None)

    def timed(self, config: tuple, repeat: int) -> float:
        return min(self.run(config)[0] for _ in range(repeat))

    def robot(self) -> dict:
        """What the MJCF needs: the scene's URDF, coordinate order, feet, PD and stops."""
        import tomllib

        from legsim.scene import bundled_dir

        bridge = self.scene.model.info["bridge"]
        with open(bundled_dir() / f"{SCENE}.toml", "rb") as f:
            raw = tomllib.load(f)
        params = raw["robot"]["parameters"]
        control = raw["controller"]["parameters"]
        names = tuple(bridge.coordinate_names)
        stops = {}
        for stop in params.get("stops", []):
            big = 10.0
            stops[stop["joint"]] = (stop["position"], big) if stop["side"] == "lower" else (-big, stop["position"])
        dofs = sorted(int(k) for k in bridge.actuated_dofs)  # MuJoCo's actuators in qpos order
        order = [names[k] for k in dofs]
        targets = dict(zip(params["actuated"], control["targets"], strict=True))
        return {
            "urdf": bundled_dir() / params["file"],
            "order": names,
            "feet": {c["frame"]: c["friction"] for c in params["contacts"]},
            "kp": control["kp"],
            "kd": control["kd"],
            "targets": [targets[n] for n in order],
            "actuated": tuple(order),
            "actuated_dofs": dofs,
            "stops": stops,
        }

    def dynamics(self, q) -> tuple[np.ndarray, np.ndarray]:
        import pinocchio as pin

        model = self.scene.model.info["bridge"].model
        data = model.createData()
        M = pin.crba(model, data, np.asarray(q, dtype=float))
        M = np.triu(M) + np.triu(M, 1).T
        g = pin.computeGeneralizedGravity(model, data, np.asarray(q, dtype=float))
        return M, np.array(g)


def sample_times(t_final: float) -> np.ndarray:
    return np.linspace(0.0, t_final, round(t_final / SAMPLE_DT) + 1)


def error(q, ref) -> float:
    if q is None or len(q) != len(ref) or not np.all(np.isfinite(q)):
        return math.inf
    return float(np.max(np.abs(np.asarray(q) - ref)))


def legsim_configs(quick: bool) -> list[tuple]:
    """(method, h, eps, rtol): rk4 and ros34pw2 with fixed steps h, ros34pw2 and dopri5 with
    error control (rtol = atol, h = 20 ms the largest step), each at several strip widths eps (m, N, m/s)."""
    fixed_eps = (1e-3, 1e-4, 1e-5) if quick else (1e-3, 1e-4, 1e-5, 1e-6)
    control_eps = (1e-2, 1e-3, 1e-4, 1e-5) if quick else (1e-2, 1e-3, 1e-4, 1e-5, 1e-6)
    configs = [("rk4", h, e, None) for h in ((1e-3,) if quick else (1e-3, 5e-4, 2.5e-4)) for e in fixed_eps]
    configs += [("ros34pw2", h, e, None) for h in (8e-3, 4e-3, 2e-3, 1e-3) for e in fixed_eps]
    rtols = (1e-1, 1e-2, 1e-3, 1e-4) if quick else (1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6)
    configs += [("ros34pw2", 2e-2, e, r) for r in rtols for e in control_eps]
    # At loose tolerances the 20 ms cap, not the error, sets the steps: longer caps there too.
    configs += [("ros34pw2", h, e, r) for h in (5e-2, 1e-1) for r in (1e-1, 1e-2, 1e-3) for e in control_eps[:3]]
    rtols = (1e-3, 1e-5) if quick else (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8)
    configs += [("dopri5", 2e-2, e, r) for r in rtols for e in control_eps]
    if not quick:
        configs += [("dopri5", 2e-2, 1e-7, r) for r in (1e-7, 1e-8)]
    return configs


def mujoco_configs(quick: bool) -> list[tuple]:
    dts = (1e-3, 2e-3, 4e-3, 8e-3) if quick else (5e-4, 1e-3, 2e-3, 4e-3, 8e-3)
    return [(integrator, dt) for integrator in ("Euler", "implicitfast", "RK4") for dt in dts]


def check_model(legsim: LegsimSide, worker: Worker, rng: np.random.Generator) -> float:
    """Largest relative difference of the mass matrices and g(q) at the initial state and random ones."""
    q0 = legsim.scene.initial_state[:7]
    states = [q0] + [q0 + rng.uniform(-1.0, 1.0, 7) for _ in range(4)]
    worst = 0.0
    for q in states:
        M, g = legsim.dynamics(q)
        other = worker.ask("dynamics", q=q.tolist())
        dM = float(np.max(np.abs(M - np.array(other["M"])))) / float(np.max(np.abs(M)))
        dg = float(np.max(np.abs(g - np.array(other["g"])))) / float(np.max(np.abs(g)))
        worst = max(worst, dM, dg)
        print(f"  q = {np.round(q, 3).tolist()}: max |dM| / max |M| = {dM:.2g}, max |dg| / max |g| = {dg:.2g}")
    return worst


def start(python: str, t_final: float) -> tuple[LegsimSide, Worker, dict, dict]:
    """Both sides loaded, the models checked; (legsim, worker, robot, MuJoCo's load reply)."""
    legsim = LegsimSide(t_final)
    robot = legsim.robot()
    xml = mjcf(
        robot["urdf"],
        robot["order"],
        robot["feet"],
        robot["kp"],
        robot["kd"],
        robot["targets"],
        robot["actuated"],
        robot["stops"],
    )
    worker = Worker(python)
    loaded = worker.ask(
        "load",
        xml=xml,
        q0=legsim.scene.initial_state[:7].tolist(),
        targets=robot["targets"],
        kp=robot["kp"],
        actuated_dofs=robot["actuated_dofs"],
    )
    if tuple(loaded["names"]) != robot["order"]:
        raise RuntimeError(f"MuJoCo's joints {loaded['names']} are not in legsim's order {robot['order']}")
    return legsim, worker, robot, loaded


def mujoco_positions(worker: Worker, config: tuple, t_final: float, repeat: int = 0, gravity: bool = True) -> dict:
    integrator, dt = config
    reply = worker.ask(
        "run",
        integrator=integrator,
        dt=dt,
        t_final=t_final,
        every=max(1, round(SAMPLE_DT / dt)),
        repeat=repeat,
        gravity=gravity,
    )
    reply["q"] = np.full((1, 1), np.nan) if reply["unstable"] else np.array(reply["q"])
    return reply


def sample_stride(dt: float) -> int:
    """Every how many reference samples (SAMPLE_DT apart) a run of step dt has a state: 1 up to
    SAMPLE_DT, then dt / SAMPLE_DT (such a run is compared at its own steps only)."""
    return max(1, round(dt / SAMPLE_DT))


def level_row(rows: list[tuple]) -> str:
    """One error level's cells from its rounds' (legsim best, MuJoCo best), each (s, config) or
    None: the median round (by the ratio legsim / MuJoCo, or by the time of the side that
    reaches the level), its times and configurations, and the ratio of every round."""
    both = all(lb is not None and mb is not None for lb, mb in rows)
    key = (lambda r: r[0][0] / r[1][0]) if both else (lambda r: (r[0] or r[1] or (math.inf,))[0])
    if all(lb is None and mb is None for lb, mb in rows):
        return "- | - | neither"
    ordered = sorted(rows, key=key)
    lb, mb = ordered[(len(ordered) - 1) // 2]
    cells = [f"{1e3 * best[0]:.3g} ms {best[1]}" if best is not None else "-" for best in (lb, mb)]
    if both:
        ratio = f"{key((lb, mb)):.3g} (rounds {', '.join(f'{key(r):.3g}' for r in rows)})"
    else:
        ratio = "only legsim" if lb is not None else "only MuJoCo"
    return " | ".join([*cells, ratio])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mujoco-python", default=DEFAULT_MUJOCO_PYTHON, help="the Python of MuJoCo's venv")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds (default 3)")
    parser.add_argument("--repeat", type=int, default=5, help="runs per configuration, best taken (default 5)")
    parser.add_argument("--t-final", type=float, default=T_FINAL, help="simulated seconds (default 1)")
    parser.add_argument("--quick", action="store_true", help="fewer configurations")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        return serve()
    print(f"uptime: {subprocess.run(['uptime'], capture_output=True, text=True).stdout.strip()}")
    legsim, worker, _robot, loaded = start(args.mujoco_python, args.t_final)
    print(
        f"MuJoCo {loaded['version']}; model compile {1e3 * loaded['compile_s']:.3g} ms; legsim scene load "
        f"{legsim.load_s:.3g} s, first run (rk4 h=1e-3, kernels from the cache) {legsim.first_run_s:.3g} s"
    )
    print("mass matrix and g(q), legsim (Pinocchio) against MuJoCo:")
    worst = check_model(legsim, worker, np.random.default_rng(0))
    if not worst <= MASS_TOLERANCE:
        print(f"refusing to compare: the models differ by {worst:.2g} relative (> {MASS_TOLERANCE:g})")
        return 2
    first = mujoco_positions(worker, ("implicitfast", 2e-3), args.t_final, repeat=1)
    print(f"MuJoCo first run (implicitfast dt=2e-3, fresh model): {1e3 * first['wall']:.3g} ms")

    t0 = time.perf_counter()
    l_ref = legsim.run(LEGSIM_REFERENCE, record=True)[1]
    l_check = legsim.run(("dopri5", 1e-3, 1e-9, 1e-11), record=True)[1]
    m_ref = mujoco_positions(worker, MUJOCO_REFERENCE, args.t_final)["q"]
    m_check = mujoco_positions(worker, ("RK4", 2 * MUJOCO_REFERENCE[1]), args.t_final)["q"]
    print(
        f"references ({time.perf_counter() - t0:.3g} s): legsim {LEGSIM_REFERENCE} vs dopri5 rtol 1e-11 "
        f"eps 1e-9: {error(l_check, l_ref):.2g}; MuJoCo {MUJOCO_REFERENCE} vs dt x2: {error(m_check, m_ref):.2g}; "
        f"the two references differ by {error(m_ref, l_ref):.2g} (contact models)"
    )

    l_configs, m_configs = legsim_configs(args.quick), mujoco_configs(args.quick)
    l_err = [error(legsim.run(c, record=True)[1], l_ref) for c in l_configs]
    m_err = [error(mujoco_positions(worker, c, args.t_final)["q"], m_ref[:: sample_stride(c[1])]) for c in m_configs]
    for c, e in zip(m_configs, m_err, strict=True):
        print(f"  MuJoCo {c[0]} dt={c[1]:g}: error {e:.2g}")
    per_level: dict[float, list[tuple]] = {lv: [] for lv in LEVELS}
    l_times, m_times = [], []
    for rnd in range(args.rounds):
        l_time, m_time = [], []
        for i in range(max(len(l_configs), len(m_configs))):  # alternate: one MuJoCo config, one legsim config
            if i < len(m_configs):
                m_time.append(mujoco_positions(worker, m_configs[i], args.t_final, args.repeat)["wall"] / args.t_final)
            if i < len(l_configs):
                l_time.append(legsim.timed(l_configs[i], args.repeat) / args.t_final)
        l_times.append(l_time)
        m_times.append(m_time)
        for lv in LEVELS:
            lb = min(((t, c) for t, c, e in zip(l_time, l_configs, l_err, strict=True) if e <= lv), default=None)
            mb = min(((t, c) for t, c, e in zip(m_time, m_configs, m_err, strict=True) if e <= lv), default=None)
            per_level[lv].append((lb, mb))
        print(f"round {rnd + 1} done ({subprocess.run(['uptime'], capture_output=True, text=True).stdout.strip()})")
    alone = [
        mujoco_positions(worker, c, args.t_final, args.repeat, gravity=False)["wall"] / args.t_final for c in m_configs
    ]
    worker.close()

    print("\nlegsim configurations (method, h, eps, rtol): error, best ms per simulated s over rounds")
    for k, (c, e) in enumerate(zip(l_configs, l_err, strict=True)):
        print(f"  {c}: {e:.2g}, {1e3 * min(t[k] for t in l_times):.3g} ms")
    print(
        "MuJoCo configurations (integrator, dt): error, best ms per simulated s over rounds; without the g(q) "
        "update (MuJoCo's step alone, not the same robot)"
    )
    for k, (c, e) in enumerate(zip(m_configs, m_err, strict=True)):
        print(f"  {c}: {e:.2g}, {1e3 * min(t[k] for t in m_times):.3g} ms; {1e3 * alone[k]:.3g} ms")
    print(
        "\nerror level | legsim best (ms per simulated s, config) | MuJoCo best"
        " | legsim / MuJoCo, median round (rounds)"
    )
    for lv in LEVELS:
        print(f"<= {lv:g} | {level_row(per_level[lv])}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
