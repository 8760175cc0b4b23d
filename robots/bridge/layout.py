"""The parameter array p of a bridge mode, by name: the one module that declares its slots.

Every model function of the bridge (``dynamics``, ``events``, ``joint``) takes a mode's p
(float64, built once per mode by ``params``); a slot is a module-level integer, which numba reads
as a constant. p starts with a header (``P_*``) whose entries are counts and the offsets of its
sections; each section is a run of fixed-size records (their fields: ``C_*`` contacts, ``L_*``
legs, ``TR_*`` transitions, ``EV_*`` events, ``J_*`` joint outcomes).

A mode is the status of each rigid contact (a point contact or a joint stop, in declared order:
``S_*``) and the set of stance spring legs. A set of statuses is also written as one number,
its *code* ``sum status_i 4^i`` (``dynamics.status_code``), which names a target mode in the
transition and joint records.

Units: SI (m, rad, N, N m, s); restitutions and friction coefficients are ratios.
"""

from __future__ import annotations

# -- the header -------------------------------------------------------------------------------
#: The native model handle; nv; the mode's state dimension (2 nv + stance footholds).
#: Actuated dofs (count, offset: (velocity index, effort limit) per entry of u, the limit in N m
#: or N, inf without one); joint damping (count,
#: offset: (dof, b) pairs); the frames whose kinematics the guards read (count, offset: frame
#: ids; a record's *slot* is an index into this list) and whether the mode's guards need them.
#: The robot's rigid contacts (count, offset of their records) and this mode's status of each
#: (offset), its code; the constraint blocks of the mode's active contacts (count, offset, their
#: rows). The spring legs (count, offset of their records) and this mode's stance legs (count).
#: The outgoing transitions (count, offset of their records); whether the robot has Coulomb
#: friction; its events (count, offset); its joint outcomes (count, offset). The terrain's
#: encoding (offset; ``legsim.terrain``), or -1 when the ground is level under each contact at its
#: own height (``C_PLACE``, ``L_GROUND``); and its highest point (m; +inf where it has none: a
#: slope), above which a round contact's centre far up is far from the ground. Whether the robot
#: has round contacts whose point nearest the ground moves in the body (``model.rounds_move``).
(
    P_HANDLE,
    P_N,
    P_DIM,
    P_NACT,
    P_ACT,
    P_NDAMP,
    P_DAMP,
    P_NFRAME,
    P_FRAME,
    P_KINEMATICS,
    P_NCONTACT,
    P_CONTACT,
    P_STATUS,
    P_CODE,
    P_NRIGID,
    P_RIGID,
    P_ROWS,
    P_NLEG,
    P_LEG,
    P_NSPRING,
    P_NGUARD,
    P_GUARD,
    P_COULOMB,
    P_NEVENT,
    P_EVENT,
    P_NJOINT,
    P_JOINT,
    P_TERRAIN,
    P_TERRAIN_TOP,
    P_ROUNDS_TURN,
) = range(30)
HEADER = 30

# -- statuses of a rigid contact in a mode --------------------------------------------------------
#: Absent (inactive); active (a stuck point, a frictionless point, a held stop); a point with
#: friction slipping towards +x or -x.
S_ABSENT, S_ACTIVE, S_SLIP_POS, S_SLIP_NEG = range(4)
#: The base of a status code.
STATUS_BASE = 4.0

# -- a constraint block (the native library's ``Rigid``: kind, id, sign, rows) -------------------
#: A joint stop (id: its dof; sign: +1 lower, -1 upper); a stuck or frictionless point (id: its
#: frame; sign: its friction coefficient mu, < 0 without one, by which a statically indeterminate
#: support shares its friction); a slipping point (sign: s mu, its friction force -s mu lambda_n
#: along the ground's tangent). On a terrain the native library takes the slope and curvature under each block
#: besides (``dynamics.terrain_slopes``).
B_STOP, B_POINT, B_SLIPPING = range(3)
BLOCK_SIZE = 4

# -- a rigid contact (``P_CONTACT`` records) -------------------------------------------------------
#: Kind (``KIND_STOP``, ``KIND_POINT``); its dof (stop) or frame id (point); a stop's side sign;
#: the stop's position (rad or m) or the ground's height (m; unused on a terrain); restitution c; friction mu (< 0:
#: none); rows when stuck (2: pinned in x and z, 1: normal only); its frame's kinematics slot
#: (-1 for a stop); the contacts it releases when it strikes (a bit mask of their indices); how
#: it is armed (``ARMED_*``), the coordinate index or frame slot it is armed by and the threshold
#: (rad, m); a round contact's radius (m, 0 for a point or a stop) and the frame at its centre
#: (its own frame's origin, without the offset to the point nearest the ground; -1 for a stop).
(
    C_KIND,
    C_ID,
    C_SIGN,
    C_PLACE,
    C_RESTITUTION,
    C_MU,
    C_ROWS,
    C_SLOT,
    C_RELEASES,
    C_ARMED,
    C_ARMED_REF,
    C_ARMED_BEYOND,
    C_RADIUS,
    C_CENTER,
) = range(14)
CONTACT_SIZE = 14
KIND_STOP, KIND_POINT = range(2)
#: Always armed; armed where a coordinate exceeds the threshold; armed where the point is ahead
#: (in x) of a frame by more than the threshold.
ARMED_ALWAYS, ARMED_COORDINATE, ARMED_AHEAD = range(3)

# -- a spring leg (``P_LEG`` records) ---------------------------------------------------------------
#: The hip's and the flight foot's kinematics slots and frame ids; stiffness k (N/m), rest length
#: l (m), damping b (N s/m), ground height (m); its foothold's index among the mode's stance
#: footholds (-1 in flight).
L_HIP_SLOT, L_FOOT_SLOT, L_HIP_FRAME, L_FOOT_FRAME, L_STIFFNESS, L_REST, L_DAMPING, L_GROUND, L_FOOTHOLD = range(9)
LEG_SIZE = 9

# -- an outgoing transition (``P_GUARD`` records, in the mode's transition order) ------------------
#: Kinds: a bounce (c > 0: the gap guard; its continuation is the plastic impact into the mode
#: with the contact active); a plastic impact's stick (side +1) or graze (side -1) transition; a
#: release (liftoff of a point, release of a stop) on the normal force; a spring leg's touchdown
#: and liftoff; one outcome of an event of a robot with friction.
K_BOUNCE, K_PLASTIC, K_RELEASE, K_LEG_TOUCH, K_LEG_LIFT, K_OUTCOME = range(6)
#: Kind; the rigid contact's (or leg's) index; a plastic pair's side; the impact's blocks
#: (offset, count: the contacts held through it, then the striker) and their restitutions
#: (offset), and the continuation's (offset: zeros); the stick mode's blocks (offset, count) and
#: the contact's normal row there (for a release: in this mode); the target's footholds (offset
#: of the map: each one's index in this mode's, or -1 for the touching leg; count); an outcome's
#: event and target code; the rigid contact a strike strikes (-1: not a strike, for the joint
#: resolution).
(
    TR_KIND,
    TR_CONTACT,
    TR_SIDE,
    TR_IMPACT,
    TR_NIMPACT,
    TR_COEFF,
    TR_REST,
    TR_STICK,
    TR_NSTICK,
    TR_ROW,
    TR_MAP,
    TR_NMAP,
    TR_EVENT,
    TR_TARGET,
    TR_STRIKE,
) = range(15)
TRANSITION_SIZE = 15

# -- an event of a robot with friction (``P_EVENT`` records) ---------------------------------------
#: Kinds: an inactive contact's strike (its gap); an active one's normal force through 0
#: (liftoff, release); a stuck one's force reaching the cone's edge towards s; a slipping one's
#: slip velocity back through 0; an active point's velocity leaving the face under it (a corner
#: of a profile passed: it strikes the new face, or leaves it).
E_GAP, E_FORCE, E_SLIP, E_STICK, E_CORNER = range(5)
#: Kind; the contact; s (E_SLIP, E_STICK); the contact's normal row in this mode; the first of
#: its transitions and how many (one per target mode).
EV_KIND, EV_CONTACT, EV_SLIP, EV_ROW, EV_FIRST, EV_COUNT = range(6)
EVENT_SIZE = 6

# -- a joint outcome (``P_JOINT`` records, in ``ModeFunctions.joint_outcomes`` order) ---------------
#: The strikers (a bit mask of rigid contact indices); 1 for the continuation (every impact
#: plastic); the target's code.
J_MASK, J_REST, J_TARGET = range(3)
JOINT_SIZE = 3
