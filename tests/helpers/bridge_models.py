"""Small planar Pinocchio models for the contact-bridge tests: a point mass on PX, PZ and a
rod on the planar floating base."""

import numpy as np
import pinocchio as pin
from legsim.robots.bridge import add_point_frame, planar_floating_base

G = 9.81


def ball_model(m=1.0):
    """A point mass m (kg) on PX, PZ with frame "ball" at it; returns (model, id of the z joint)."""
    model = pin.Model()
    jx = model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "x")
    jz = model.addJoint(jx, pin.JointModelPZ(), pin.SE3.Identity(), "z")
    model.appendBodyToJoint(jz, pin.Inertia(m, np.zeros(3), np.zeros((3, 3))), pin.SE3.Identity())
    add_point_frame(model, "ball", jz, (0, 0, 0))
    return model, jz


def rod_model(m=1.0, I=0.3, L=1.0):  # noqa: E741 - I is the inertia, as callers name it
    """A rod (mass m kg, inertia I kg m^2) on the planar floating base, frame "tip" at L/2 (m) along it."""
    model = pin.Model()
    body = planar_floating_base(model)
    model.appendBodyToJoint(body, pin.Inertia(m, np.zeros(3), np.diag([I, I, I])), pin.SE3.Identity())
    add_point_frame(model, "tip", body, (L / 2, 0, 0))
    return model
