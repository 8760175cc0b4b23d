"""Contact declarations of the bridge: bad models, contacts and names are refused with
messages that name them."""

import pinocchio as pin
import pytest
from legsim.robots import pronk
from legsim.robots.bridge import ContactBridge, JointStop, PointContact, SpringLeg

from helpers.bridge_models import ball_model
from legsim import ModelError, SceneError


def test_bad_models_and_contacts_are_named():
    model, _ = ball_model()
    with pytest.raises(ModelError, match="unknown frame 'nope'"):
        ContactBridge(model, [PointContact("foot", "nope")])
    with pytest.raises(ModelError, match="duplicate contact name 'foot'"):
        ContactBridge(model, [PointContact("foot", "ball"), PointContact("foot", "ball")])
    with pytest.raises(ModelError, match="contact 'foot': restitution must be <= 1"):
        ContactBridge(model, [PointContact("foot", "ball", restitution=1.5)])
    with pytest.raises(ModelError, match="contact 'leg': stiffness must be > 0"):
        ContactBridge(model, [SpringLeg("leg", "ball", stiffness=0.0, rest_length=1.0)])
    with pytest.raises(ModelError, match="stop 'stop': unknown joint 'elbow'"):
        ContactBridge(model, [JointStop("stop", "elbow")])
    with pytest.raises(ModelError, match="side must be 'lower' or 'upper'"):
        ContactBridge(model, [JointStop("stop", "z", side="left")])
    with pytest.raises(ModelError, match="releases unknown contact 'heel'"):
        ContactBridge(model, [PointContact("toe", "ball", releases=("heel",))])
    with pytest.raises(ModelError, match="contacts must be PointContact, JointStop or SpringLeg"):
        ContactBridge(model, ["foot"])
    with pytest.raises(ModelError, match="mode_names names unknown contact"):
        ContactBridge(model, [], mode_names={("foot",): "stance"})
    unbounded = pin.Model()
    unbounded.addJoint(0, pin.JointModelRUBY(), pin.SE3.Identity(), "wheel")
    with pytest.raises(ModelError, match=r"nq == model\.nv"):
        ContactBridge(unbounded)
    with pytest.raises(ModelError, match=r"pinocchio\.Model"):
        ContactBridge("robot.urdf")
    # builder parameters are checked before anything is built
    with pytest.raises(SceneError, match=r"robot.parameters.k: -1.0 is out of range"):
        pronk.make({"k": -1.0})
