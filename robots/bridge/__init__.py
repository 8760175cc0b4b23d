"""The contact-mode bridge: a planar Pinocchio model plus its contacts -> a ``legsim.HybridSystem``."""

from .assembly import ContactBridge, JointStop, PointContact, SpringLeg, add_point_frame, planar_floating_base

__all__ = ["ContactBridge", "JointStop", "PointContact", "SpringLeg", "add_point_frame", "planar_floating_base"]
