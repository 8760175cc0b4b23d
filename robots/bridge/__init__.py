"""The contact-mode bridge: a planar Pinocchio model plus its contacts -> a ``legsim.HybridSystem``.

A *mode* is the set of active contacts. Three kinds of contact are supported:

``PointContact``
    the origin of a Pinocchio frame meets the ground ``z = ground``. Inactive: a touchdown
    guard; active: a rigid (bilateral while active) constraint pinning the point (``x`` and
    ``z``, or ``z`` only when ``tangential=False``) with a release guard on the normal force.
    It may name contacts it ``releases`` when it strikes (a walker's stance foot at heel strike:
    they are dropped before the impact is solved), and be ``armed`` only in part of the
    configuration space (``Armed``: where a coordinate or its lead over a frame passes a
    threshold).
``JointStop``
    a one-dof joint meets a stop at ``position`` (``side="lower"``: domain ``q >= position``,
    ``"upper"``: ``q <= position``). Inactive: an impact guard; active: the joint is held at
    the stop, with a release guard on the stop's generalised force.
``SpringLeg``
    a massless linear spring leg hinged at a frame (the hip). In flight the leg keeps its rest
    length and the angle ``angle`` from the hip frame's ``-z`` axis towards its ``+x`` axis; its
    foot is an extra Pinocchio frame ``<name>_foot``. At touchdown the foot is pinned where it
    meets the ground and its horizontal position (the *foothold*) joins the state; the leg
    pushes on the hip with ``k (l - r)`` (minus ``b dr/dt`` with damping) along the leg; liftoff
    when the leg is back at its rest length, which drops the foothold.

The state is ``x = (q, v, footholds)`` with ``q`` and ``v`` of size ``nv`` (the bridge needs
``model.nq == model.nv``: prismatic and bounded revolute joints, the planar robots' case) and one
foothold (m) per active spring leg, in the declared order. A rigid impact with c = 0 enters the
mode with the contact active (or grazes off when the contact would pull); c > 0 bounces back into
the same mode (possibly Zeno). Modes are built lazily (``HybridSystem(expand=...)``): only those a
transition reaches are ever constructed.

Every mode is written once, as model functions over its parameter array (``legsim.model``),
calling Pinocchio's C++ algorithms through the native library: the Python loop and the compiled
kernel evaluate the same functions. Modules:

* ``contacts``: the declarations, their validation and resolution; ``planar_floating_base``,
  ``add_point_frame``;
* ``model``: ``BridgeModel`` (the resolved robot and its native handle); ``native``: the handle
  and the robot's evaluation counters;
* ``modes``: mode names, ``ModeSpec`` (active contacts, statuses, state layout);
* ``layout``: the slots of a mode's parameter array; ``params``: building it;
* ``transitions``: the outgoing transitions of a mode, their records, its joint outcomes;
* model functions: ``dynamics`` (applied forces, the forward dynamics and the KKT solve: the field),
  ``events`` (guards and resets), ``impacts`` (Newton's impact, simultaneous strikes, the
  frictional impact), ``friction`` (the mode after an event), ``joint`` (simultaneous strikes);
* ``guards``: the initial-state check and the guards' units;
* ``assembly``: ``ContactBridge``, the facade composing them.

A robot's native model has one Pinocchio data: a system built on it is not thread-safe.
"""

from .assembly import ContactBridge
from .contacts import Armed, Contact, JointStop, PointContact, SpringLeg, add_point_frame, planar_floating_base

__all__ = [
    "Armed",
    "Contact",
    "ContactBridge",
    "JointStop",
    "PointContact",
    "SpringLeg",
    "add_point_frame",
    "planar_floating_base",
]
