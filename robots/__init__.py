"""Robots for legsim: Pinocchio models turned into hybrid systems by the contact-mode bridge.

* ``legsim.robots.bridge``: ``ContactBridge`` (a Pinocchio model + ``PointContact`` / ``JointStop`` /
  ``SpringLeg`` records -> ``legsim.HybridSystem``, one mode per set of active contacts) and the
  model helpers ``planar_floating_base`` and ``add_point_frame``.
* ``legsim.robots.double_pendulum``, ``legsim.robots.pronk``, ``legsim.robots.slip``: the papers' robots, each with
  named coordinates, default parameters and a ``BUILDER`` that scenes find through the
  ``legsim.builders`` entry points.

The core (``legsim``) never imports this package.
"""

from .bridge import ContactBridge, JointStop, PointContact, SpringLeg, add_point_frame, planar_floating_base

__all__ = ["ContactBridge", "JointStop", "PointContact", "SpringLeg", "add_point_frame", "planar_floating_base"]
