"""Every bundled scene, in the list of the tests that run it on the compiled path: the robots'
(``tests/robots/test_compiled_robots.py``) and the systems written once
(``tests/systems/test_written_once.py``). ``test_every_bundled_scene_is_checked_on_the_compiled_path``
keeps the two lists complete."""

#: Every bundled scene of a robot, with a shorter run where the scene's own is long.
ROBOT_SCENES = [
    ("compass_gait", None),
    ("rimless_wheel", None),
    ("double_pendulum_pd", "2.0"),
    ("double_pendulum_plastic", "3.0"),
    ("double_pendulum_plastic_paper", "3.0"),
    ("double_pendulum_zeno", "3.0"),
    ("double_pendulum_zeno_paper", "3.0"),
    ("rod", None),
    ("pronk", None),
    ("pronk_paper", None),
    ("pronk_pitched", None),
    ("pronk_pitched_paper", None),
    ("slip", None),
    ("quadruped_stand", None),
    ("quadruped_pronk", "2.0"),
    ("quadruped_run", "2.0"),
    ("quadruped_bound", "2.0"),
    ("quadruped_pronk_forward", "2.0"),
    ("quadruped_bound_forward", "2.0"),
    ("quadruped_gallop", "2.0"),
    ("quadruped_bound_one_flight", "2.0"),
    ("quadruped_bound_steps", "2.0"),
    ("biped_run", "2.0"),
]

#: The bundled scenes of the systems written once, and an end time for the interpreted runs
#: (None: the scene's own), long enough for several transitions of each.
SYSTEM_SCENES = {
    "bouncing_ball": None,
    "oscillator_ex1": 20.0,
    "oscillator_ex2": None,
    "two_tanks": None,
    "digital_control": None,
    "grazing": None,
    "slip_raibert": 3.0,
    "pronk_raibert": 3.0,
    "slip_orbit": 3.0,
    "pronk_orbit": 3.0,
}
