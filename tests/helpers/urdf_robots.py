"""URDF robots written into a test's folder (none of them bundled), with their scenes: a monoped
(a 10 kg box trunk on a prismatic leg with a point foot) and a slider (a mass on a vertical
prismatic joint, fixed to the world)."""

from pathlib import Path

#: The monoped's trunk box (m): half length along x and half height along z.
TRUNK_HALF_X, TRUNK_HALF_Z = 0.3, 0.1

MONOPED_URDF = f"""<?xml version="1.0"?>
<robot name="monoped">
  <link name="trunk">
    <inertial><mass value="10"/><inertia ixx="0.05" iyy="0.35" izz="0.35" ixy="0" ixz="0" iyz="0"/></inertial>
    <visual><geometry><box size="{2 * TRUNK_HALF_X} 0.2 {2 * TRUNK_HALF_Z}"/></geometry></visual>
  </link>
  <joint name="slide" type="prismatic">
    <parent link="trunk"/>
    <child link="leg"/>
    <origin xyz="0 0 -0.1"/>
    <axis xyz="0 0 1"/>
    <limit lower="-0.5" upper="0.5" effort="500" velocity="10"/>
  </joint>
  <link name="leg">
    <inertial><origin xyz="0 0 -0.25"/><mass value="1"/>
      <inertia ixx="0.02" iyy="0.02" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial>
    <visual><origin xyz="0 0 -0.25"/><geometry><cylinder radius="0.02" length="0.5"/></geometry></visual>
  </link>
  <joint name="ankle" type="fixed">
    <parent link="leg"/>
    <child link="foot"/>
    <origin xyz="0 0 -0.5"/>
  </joint>
  <link name="foot"/>
  <joint name="nose_mount" type="fixed">
    <parent link="trunk"/>
    <child link="nose"/>
    <origin xyz="{TRUNK_HALF_X} 0 -{TRUNK_HALF_Z}"/>
  </joint>
  <link name="nose"/>
</robot>
"""

MONOPED_SCENE = """[robot]
name = "urdf"
[robot.parameters]
file = "monoped.urdf"
actuated = ["slide"]
contacts = [{ name = "foot", frame = "foot", friction = 1.0 }]
[controller]
name = "joint_pd"
[controller.parameters]
kp = 2000.0
kd = 50.0
[initial]
state = { z = 0.7, pitch = 0.3 }
[integrator]
h = 1e-3
eps = 1e-4
t_final = 1.5
"""

#: The slider: mass (kg), the URDF's effort limit (N), gravity (m/s^2); the scene's PD gain
#: (N/m, no damping, no gravity compensation) holding it at 0.
SLIDER_MASS, SLIDER_EFFORT, G, SLIDER_KP = 1.0, 5.0, 9.81, 100.0

SLIDER_URDF = f"""<?xml version="1.0"?>
<robot name="slider">
  <link name="base"/>
  <joint name="lift" type="prismatic">
    <parent link="base"/>
    <child link="load"/>
    <origin xyz="0 0 1"/>
    <axis xyz="0 0 1"/>
    <limit lower="-10" upper="10" effort="{SLIDER_EFFORT}" velocity="100"/>
  </joint>
  <link name="load">
    <inertial><mass value="{SLIDER_MASS}"/>
      <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
</robot>
"""

SLIDER_SCENE = f"""[robot]
name = "urdf"
[robot.parameters]
file = "slider.urdf"
root = "fixed"
actuated = ["lift"]
[controller]
name = "joint_pd"
[controller.parameters]
kp = {SLIDER_KP}
kd = 0.0
gravity = false
[integrator]
h = 1e-3
eps = 1e-4
t_final = 1.0
"""


def write(folder: Path, name: str, urdf: str, scene: str, extra: str = "") -> Path:
    """``<name>.urdf`` and ``<name>.toml`` (the scene, with ``extra`` appended) in folder; the
    scene's path."""
    (folder / f"{name}.urdf").write_text(urdf)
    path = folder / f"{name}.toml"
    path.write_text(scene + extra)
    return path


def monoped(folder: Path, extra: str = "") -> Path:
    return write(folder, "monoped", MONOPED_URDF, MONOPED_SCENE, extra)


def slider(folder: Path, extra: str = "") -> Path:
    return write(folder, "slider", SLIDER_URDF, SLIDER_SCENE, extra)
