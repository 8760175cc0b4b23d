"""The benches' case names, without importing the benches: the command line lists them in its
usage lines (``legsim bench work-precision --case {...}``), and every command module is imported
at each start of ``legsim``."""

#: The work-precision cases (``legsim.bench.cases.make_case``).
CASE_NAMES = ("oscillator-ex1", "oscillator-ex2", "bouncing-ball", "pronk", "double-pendulum")
#: The robots' bench: the uncontrolled cases, run by default (``legsim.bench.robots``).
ROBOT_CASES = ("compass-gait", "rimless-wheel", "pronk", "double-pendulum")
#: The controlled runners: opt-in by name, since they would add 30-45 s (measured at load 5-7)
#: to the default's 1.5 min, past the 2 min it aims at.
ROBOT_CONTROLLED = ("slip-raibert", "pronk-raibert", "double-pendulum-pd", "quadruped-run")
