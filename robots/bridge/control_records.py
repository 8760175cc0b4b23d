"""The kinds of control record a bridge robot's compiled twin computes (``twin_build.controls_of``).

A record sits at p[P_CTRL] of the twin's parameters: its kind, then its values, written by
Python at every mode entry. ``CTRL_NONE``: no control (a run without one; no torque).
``CTRL_JOINT_PD``: ``(kind, kp, kd, gravity, target of each actuated joint)``,
u = kp (target - q) - kd dq/dt (+ the actuated joints' generalised gravity g(q) when gravity is
1) on the actuated joints (N m or N; kp in N m/rad, kd in N m s/rad). ``CTRL_RUNNER``: Raibert's
runner for articulated legs (``robots.runner_twin``: its layout).
"""

CONTROL_KINDS = ("none", "joint_pd", "raibert_runner")
CTRL_NONE, CTRL_JOINT_PD, CTRL_RUNNER = range(len(CONTROL_KINDS))
CONTROL_HEAD = 4  # a joint PD's kind and three values before the per-joint entries
