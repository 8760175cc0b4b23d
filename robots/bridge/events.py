"""Guards and resets of the bridge's modes, as model functions (``legsim.model``) over the mode's
parameter array p (``layout``).

Guards (``>= 0`` inside the domain; their units are eps's):

* an inactive rigid contact's gap: a point's ``max(z - ground, dz/dt)`` (m), past only while it
  closes (on a terrain ``max(z - h(x), dz/dt - h'(x) dx/dt)``: the height above the terrain under
  the point, which is continuous across a profile's corners); a stop's ``max(s (q_j - position),
  s dq_j/dt)`` (rad or m), s = +1 for a lower stop and -1 for an upper one; an *armed* point
  also takes ``-armed`` (``contacts.Armed``), so that it lands only where it is armed;
* a plastic impact (c = 0) is two transitions with the gap's guard, which the post-impact
  normal force lambda+ (in the mode with the contact active, under u) splits: ``max(gap,
  -lambda+)`` sticks (``touchdown_<c>``, ``impact_<c>``) and ``max(gap, lambda+)`` separates at
  once (``graze_<c>``), so exactly one of them is past; a bouncing one (c > 0) is ``bounce_<c>``,
  continued by ``rest_<c>`` (the plastic impact into the mode with it active) when its bounces
  accumulate;
* an active rigid contact's release: its normal force (N, or N m for a stop) under u;
* a spring leg: touchdown ``z - ground`` of its flight foot while it descends (``max(z, dz/dt)``
  while it rises: a scuff); liftoff ``max(l - r, -dr/dt)`` (m).

With Coulomb friction every event (a strike, a liftoff, a stuck contact's force reaching the
cone's edge ``mu lambda_n + s lambda_t`` (N), a slipping contact's ``max(s v_t, s a_t)`` (m/s),
on a terrain with corners a sliding point's ``corner_base`` (m/s))
may lead to several modes (``friction``): it has one transition per possible target, whose
guard is the event's *base* guard where the impact law chooses that target and its absolute
value elsewhere, so only the chosen one is ever past.

The models have no body-ground contact: a hip below the ground, or a liftoff that would swing a
foot into the ground while it moves down, is past the model's range, as is an event without a
consistent outcome: every guard (and a reset's image) is then nan.
"""

from __future__ import annotations

import math

import numpy as np
from legsim.robots._native.calls import lsn_frame_motion, lsn_frames, lsn_impact

from legsim.compiled.functions import model_function, scratch
from legsim.heights import face_slope, height, second_contact

from .dynamics import (
    SLOPE_ENTRIES,
    accelerate,
    frame_kinematics,
    handle,
    mode_accelerate,
    on_terrain,
    one_frame_kinematics,
    place_rounds,
    point_slope,
    ptr,
    round_centre,
    round_record,
    status_code,
    stuck_mu,
    terrain_slopes,
    turning,
)
from .friction import event_outcome, mode_change, realize
from .layout import (
    ARMED_AHEAD,
    ARMED_COORDINATE,
    C_ARMED,
    C_ARMED_BEYOND,
    C_ARMED_REF,
    C_CENTER,
    C_ID,
    C_KIND,
    C_PLACE,
    C_RADIUS,
    C_SIGN,
    C_SLOT,
    CONTACT_SIZE,
    E_CORNER,
    E_FORCE,
    E_GAP,
    E_SLIP,
    E_STICK,
    EV_CONTACT,
    EV_COUNT,
    EV_FIRST,
    EV_KIND,
    EV_ROW,
    EV_SLIP,
    EVENT_SIZE,
    K_BOUNCE,
    K_LEG_TOUCH,
    K_OUTCOME,
    K_PLASTIC,
    K_RELEASE,
    KIND_STOP,
    L_FOOT_FRAME,
    L_FOOT_SLOT,
    L_FOOTHOLD,
    L_GROUND,
    L_HIP_SLOT,
    L_REST,
    LEG_SIZE,
    P_CODE,
    P_CONTACT,
    P_COULOMB,
    P_EVENT,
    P_GUARD,
    P_KINEMATICS,
    P_LEG,
    P_N,
    P_NCONTACT,
    P_NEVENT,
    P_NFRAME,
    P_NGUARD,
    P_ROWS,
    P_TERRAIN,
    TR_COEFF,
    TR_CONTACT,
    TR_EVENT,
    TR_IMPACT,
    TR_KIND,
    TR_MAP,
    TR_NIMPACT,
    TR_NMAP,
    TR_NSTICK,
    TR_REST,
    TR_ROW,
    TR_SIDE,
    TR_STICK,
    TR_TARGET,
    TRANSITION_SIZE,
)


@model_function
def record(p, e):
    """Offset of transition e's record in p."""
    return int(p[P_GUARD]) + TRANSITION_SIZE * e


@model_function
def gap(x, p, contact, kin):
    """The gap guard of the inactive rigid contact ``contact`` (module docstring), from the
    frames' kinematics kin."""
    n = int(p[P_N])
    c = int(p[P_CONTACT]) + CONTACT_SIZE * contact
    if p[c + C_KIND] == KIND_STOP:
        dof, sign = int(p[c + C_ID]), p[c + C_SIGN]
        return max(sign * (x[dof] - p[c + C_PLACE]), sign * x[n + dof])
    slot = 4 * int(p[c + C_SLOT])
    if p[c + C_RADIUS] > 0.0 and turning(p):
        value = round_gap(x, p, c)
    elif on_terrain(p):
        terrain, px = int(p[P_TERRAIN]), kin[slot]
        grade = face_slope(p, terrain, px, kin[slot + 2])
        value = max(kin[slot + 1] - height(p, terrain, px), kin[slot + 3] - grade * kin[slot + 2])
    else:
        value = max(kin[slot + 1] - p[c + C_PLACE], kin[slot + 3])
    armed = p[c + C_ARMED]
    if armed == ARMED_COORDINATE:
        value = max(value, -(x[int(p[c + C_ARMED_REF])] - p[c + C_ARMED_BEYOND]))
    elif armed == ARMED_AHEAD:
        value = max(value, -(kin[slot] - kin[4 * int(p[c + C_ARMED_REF])] - p[c + C_ARMED_BEYOND]))
    return value


@model_function
def round_gap(x, p, c):
    """The gap guard of the inactive round contact at record c on a terrain whose normal turns:
    ``max(d - r, dd/dt)`` (m, m/s), d the distance from its centre to the terrain (along the
    normal at the terrain's point nearest it) and dd/dt = n . v_centre, past only while it closes."""
    kin = scratch(4)
    _, d, g, _ = round_centre(x, p, c, kin)
    return max(d - p[c + C_RADIUS], (kin[3] - g * kin[2]) / math.sqrt(1.0 + g * g))


@model_function
def leg_touchdown(p, leg, kin):
    """Touchdown guard of a flight leg's foot; nan past the model's range (its hip below the
    ground). A foot below the ground while rising is in flight (the leg swung forward at liftoff
    scuffs the ground near a periodic gait); one that turns down while still below it is past
    by its depth, not by its velocity: no step lands in the strip, and the run ends
    (halving_exhausted) rather than pinning a foot that never came out of the ground."""
    foot, hip, ground = 4 * int(p[leg + L_FOOT_SLOT]), 4 * int(p[leg + L_HIP_SLOT]), p[leg + L_GROUND]
    if kin[hip + 1] - ground < 0.0:
        return math.nan
    z, vz = kin[foot + 1] - ground, kin[foot + 3]
    return z if vz <= 0.0 else max(z, vz)


@model_function
def leg_liftoff(x, p, leg, kin):
    """Liftoff guard ``max(l - r, -dr/dt)`` of a stance leg; nan past the model's range (its hip
    below the ground, or, past liftoff, its foot swung to the flight angle below the ground and
    moving down: the runner fell). Below the ground but rising is a scuff, which every symmetric
    running gait grazes, within rounding."""
    n = int(p[P_N])
    foot, hip, ground = 4 * int(p[leg + L_FOOT_SLOT]), 4 * int(p[leg + L_HIP_SLOT]), p[leg + L_GROUND]
    dx = kin[hip] - x[2 * n + int(p[leg + L_FOOTHOLD])]
    dz = kin[hip + 1] - ground
    if dz < 0.0:
        return math.nan
    r = math.hypot(dx, dz)
    rdot = (dx * kin[hip + 2] + dz * kin[hip + 3]) / r
    value = max(p[leg + L_REST] - r, -rdot)
    if value < 0.0 and kin[foot + 1] - ground < 0.0 and kin[foot + 3] < 0.0:
        return math.nan
    return value


@model_function
def impact(x, p, tr, coefficients, out):
    """The image of transition record tr's impact (its blocks, with the restitutions at
    p[coefficients]) at x into out: x with the post-impact velocity."""
    n = int(p[P_N])
    out[: x.shape[0]] = x
    count, at = int(p[tr + TR_NIMPACT]), int(p[tr + TR_IMPACT])
    slopes = scratch(SLOPE_ENTRIES * max(1, count))
    terrain_slopes(x, p, count, p, at, slopes)
    lsn_impact(handle(p), x.ctypes.data, ptr(x, n), np.int64(count), ptr(p, at), slopes.ctypes.data,
               ptr(p, coefficients), ptr(out, n), np.int64(0))  # fmt: skip


@model_function
def post_impact_force(x, u, p, tr):
    """lambda+ of a plastic impact: the striking contact's normal force (N or N m) in the mode
    with it active, right after the impact, under u."""
    n = int(p[P_N])
    after = scratch(x.shape[0])
    impact(x, p, tr, int(p[tr + TR_COEFF]), after)
    a = scratch(n)
    lam = scratch(int(p[tr + TR_ROW]) + 1 + 2 * int(p[tr + TR_NSTICK]))
    accelerate(after, u, p, int(p[tr + TR_NSTICK]), p, int(p[tr + TR_STICK]), a, lam)
    return lam[int(p[tr + TR_ROW])]


@model_function
def plain_guard(x, u, p, tr, kin, lam, solved):
    """The guard of transition record tr of a robot without friction (module docstring); lam
    holds the mode's constraint forces once solved[0] is 1 (solved here when first needed)."""
    kind = p[tr + TR_KIND]
    contact = int(p[tr + TR_CONTACT])
    if kind == K_BOUNCE:
        return gap(x, p, contact, kin)
    if kind == K_PLASTIC:
        base = gap(x, p, contact, kin)
        return base if base >= 0.0 else max(base, -p[tr + TR_SIDE] * post_impact_force(x, u, p, tr))
    if kind == K_RELEASE:
        if solved[0] == 0.0:
            mode_accelerate(x, u, p, scratch(int(p[P_N])), lam)
            solved[0] = 1.0
        return lam[int(p[tr + TR_ROW])]
    return leg_guard(x, p, tr, kin)


@model_function
def leg_guard(x, p, tr, kin):
    """The touchdown or liftoff guard of a spring leg's transition record tr."""
    leg = int(p[P_LEG]) + LEG_SIZE * int(p[tr + TR_CONTACT])
    return leg_touchdown(p, leg, kin) if p[tr + TR_KIND] == K_LEG_TOUCH else leg_liftoff(x, p, leg, kin)


@model_function
def bridge_guards(t, x, u, p, g):
    """Every outgoing transition's guard of the mode at (t, x) under u, in their order, into g;
    all nan past the model's range (module docstring)."""
    place_rounds(x, p)
    kin = scratch(4 * max(1, int(p[P_NFRAME])))
    if p[P_KINEMATICS] != 0.0:  # the frames' kinematics, when the mode's guards read them
        frame_kinematics(x, p, kin)
    count = int(p[P_NGUARD])
    if p[P_COULOMB] != 0.0:
        coulomb_guards(x, u, p, kin, g)
    else:
        lam = scratch(max(1, int(p[P_ROWS])))
        solved = scratch(1)
        solved[0] = 0.0
        for e in range(count):
            g[e] = plain_guard(x, u, p, record(p, e), kin, lam, solved)
    for e in range(count):
        if g[e] != g[e]:
            g[:count] = math.nan
            return


@model_function
def leg_reset(x, p, tr, out):
    """A spring leg's touchdown or liftoff: q and v kept, the footholds mapped (kept, dropped, or
    the touching foot's x at q)."""
    n = int(p[P_N])
    out[: 2 * n] = x[: 2 * n]
    at = int(p[tr + TR_MAP])
    kin = scratch(4)
    for i in range(int(p[tr + TR_NMAP])):
        j = int(p[at + i])
        if j >= 0:
            out[2 * n + i] = x[2 * n + j]
        else:
            leg = int(p[P_LEG]) + LEG_SIZE * int(p[tr + TR_CONTACT])
            lsn_frames(handle(p), x.ctypes.data, ptr(x, n), np.int64(1), ptr(p, leg + L_FOOT_FRAME), kin.ctypes.data)
            out[2 * n + i] = kin[0]


@model_function
def bridge_reset(e, t, x, u, p, out):
    """The image of outgoing transition e at x under u into out (its target's layout); for
    e >= the guard count, the continuation of transition e - count: an impact replaces v by the
    post-impact velocity (a bounce's continuation: the same impact, plastic); a release keeps
    x; a leg maps the footholds; an event's outcome is the impact law's (nan: no outcome)."""
    place_rounds(x, p)
    count = int(p[P_NGUARD])
    continued = e >= count
    tr = record(p, e - count if continued else e)
    kind = p[tr + TR_KIND]
    if kind == K_OUTCOME:
        outcome_image(x, u, p, tr, continued, out)
    elif kind == K_BOUNCE:
        impact(x, p, tr, int(p[tr + (TR_REST if continued else TR_COEFF)]), out)
    elif kind == K_PLASTIC:
        impact(x, p, tr, int(p[tr + TR_COEFF]), out)
    elif kind == K_RELEASE:
        out[: x.shape[0]] = x
    else:
        leg_reset(x, p, tr, out)


# -- robots with Coulomb friction -----------------------------------------------------------


@model_function
def event_base(x, p, ev, kin, a, lam):
    """The base guard of event record ev, from the mode's acceleration a and forces lam."""
    kind = p[ev + EV_KIND]
    contact = int(p[ev + EV_CONTACT])
    row = int(p[ev + EV_ROW])
    if kind == E_GAP:
        return gap(x, p, contact, kin)
    if kind == E_FORCE:
        return lam[row]
    s = p[ev + EV_SLIP]
    c = int(p[P_CONTACT]) + CONTACT_SIZE * contact
    if kind == E_CORNER:
        return corner_base(x, p, int(p[c + C_ID]))
    if kind == E_SLIP:
        return stuck_mu(x, p, c) * lam[row] + s * lam[row - 1]
    n = int(p[P_N])
    motion = scratch(4)
    lsn_frame_motion(handle(p), x.ctypes.data, ptr(x, n), a.ctypes.data, np.int64(p[c + C_ID]), motion.ctypes.data)
    if on_terrain(p):  # the slip velocity and acceleration along the terrain's tangent
        grade, norm = point_slope(x, p, int(p[c + C_ID]), scratch(4))
        return max(s * (motion[0] + grade * motion[1]) / norm, s * (motion[2] + grade * motion[3]) / norm)
    return max(s * motion[0], s * motion[2])


#: When an active point's velocity counts as leaving the face under it: its normal part beyond
#: ``CORNER_SINE`` of its speed plus ``CORNER_FLOOR`` (m/s). Passing a corner of a profile turns
#: the face by the corner's angle, so the normal part jumps to the speed times its sine; the
#: constraint holds it at 0 on a face only to its drift (the forces keep the acceleration on the
#: face, not the velocity: a few um/s over a stance). Corners of less than 0.6 degrees, or
#: passed slower than 0.1 mm/s, are taken as smooth.
CORNER_SINE, CORNER_FLOOR = 1e-2, 1e-4
#: How far (m) an active point may lie below the face under it before it counts as having passed
#: a concave corner: far above the drift of its height on a face, far below any step. A step
#: that carries a sliding point over a face narrower than itself (a 1 mm riser) never lands
#: where the normal speed has jumped, but it does land below the ground.
CORNER_DEPTH = 1e-5


@model_function
def corner_base(x, p, frame):
    """The corner event's base guard of the active point at Pinocchio frame ``frame`` (m/s, or m
    for its depth): ``CORNER_SINE |v| + CORNER_FLOOR - |v_n|``, v_n its velocity along the
    normal of the face under it, and at most its height above that face plus ``CORNER_DEPTH``. On
    a face the constraint keeps v_n and the height near 0; past a corner of the profile the
    face's normal turns and v_n jumps (into the new face at a concave corner, away from it at a
    convex one): the loop crosses that jump (``ModeFunctions.crosses_jumps``). A round contact's
    is its centre's: v_n along the normal at the terrain's point nearest it, the height its
    distance less r; the normal turns smoothly round a convex corner and jumps only where the
    centre crosses a concave corner's bisector, onto the face it then strikes."""
    kin = scratch(4)
    c = round_record(p, frame) if turning(p) else -1
    if c >= 0:
        _, distance, grade, _ = round_centre(x, p, c, kin)
        norm = math.sqrt(1.0 + grade * grade)
        clearance = distance - p[c + C_RADIUS]
    else:
        grade, norm = point_slope(x, p, frame, kin)
        clearance = kin[1] - height(p, int(p[P_TERRAIN]), kin[0])
    normal_speed = (kin[3] - grade * kin[2]) / norm
    turned = CORNER_SINE * math.hypot(kin[2], kin[3]) + CORNER_FLOOR - abs(normal_speed)
    return min(turned, clearance + CORNER_DEPTH)


@model_function
def wedged(p, contact, image):
    """Whether the round contact ``contact``, striking the profile (landing, or passing a concave
    corner), touches it at a second point too (another face in a notch, an edge across a pit
    narrower than itself: ``legsim.heights.second_contact``) and its centre moves, after the
    strike (``image``), into that one: a strike on two points at once, which the impact law taken
    at one point does not answer (the outcome is then refused: the run stops, past the model's
    range)."""
    c = int(p[P_CONTACT]) + CONTACT_SIZE * contact
    if p[c + C_RADIUS] <= 0.0 or not turning(p):
        return False
    kin = scratch(4)
    one_frame_kinematics(image, p, int(p[c + C_CENTER]), kin)
    grade = second_contact(p, int(p[P_TERRAIN]), kin[0], kin[1], CORNER_DEPTH)
    if math.isnan(grade):
        return False
    return (kin[3] - grade * kin[2]) / math.sqrt(1.0 + grade * grade) < -CORNER_FLOOR


@model_function
def outcome(x, u, p, ev, rest, status, image):
    """The mode (status) and image after event record ev at x under u (``friction``); False
    where the law has no outcome."""
    kind = p[ev + EV_KIND]
    contact = int(p[ev + EV_CONTACT])
    if kind == E_GAP or kind == E_CORNER:  # noqa: SIM109 -- two float compares, no tuple in compiled code
        return event_outcome(x, u, p, 1 << contact, rest, -1, status, image) and not wedged(p, contact, image)
    if kind == E_STICK:
        return event_outcome(x, u, p, 0, False, contact, status, image)
    return mode_change(x, u, p, contact, p[ev + EV_SLIP], kind == E_FORCE, status, image)


@model_function
def coulomb_guards(x, u, p, kin, g):
    """The guards of a mode of a robot with friction into g: each event's transitions from its
    base and, where the base is past, its outcome (module docstring); the legs' as without.
    A point past a corner takes precedence: the other events' bases, whose forces and slip
    velocities jumped with the face's normal, count as not past until it has struck the new
    face or left it."""
    n, contacts = int(p[P_N]), int(p[P_NCONTACT])
    a, lam = scratch(n), scratch(max(1, int(p[P_ROWS])))
    events = int(p[P_NEVENT])
    solved = False
    bases = scratch(max(1, events))
    status, image = scratch(max(1, contacts)), scratch(x.shape[0])  # for an outcome, the rare case
    cornered = False
    for k in range(events):
        ev = int(p[P_EVENT]) + EVENT_SIZE * k
        if p[ev + EV_KIND] != E_GAP and not solved:
            mode_accelerate(x, u, p, a, lam)
            solved = True
        bases[k] = event_base(x, p, ev, kin, a, lam)
        cornered = cornered or (p[ev + EV_KIND] == E_CORNER and bases[k] < 0.0)
    for k in range(events):
        ev = int(p[P_EVENT]) + EVENT_SIZE * k
        base = abs(bases[k]) if cornered and p[ev + EV_KIND] != E_CORNER else bases[k]
        first, copies = int(p[ev + EV_FIRST]), int(p[ev + EV_COUNT])
        chosen = math.nan
        if base < 0.0:  # past: the outcome decides which copy
            if not outcome(x, u, p, ev, False, status, image):
                g[first] = math.nan
                return
            code = status_code(status, contacts)
            # nothing strikes: a point grazing the ground without approaching it
            chosen = math.nan if code == p[P_CODE] and np.all(image == x) else code
        for e in range(first, first + copies):
            g[e] = base if base >= 0.0 or p[record(p, e) + TR_TARGET] == chosen else -base
    for e in range(int(p[P_NGUARD])):
        tr = record(p, e)
        if p[tr + TR_KIND] != K_OUTCOME:
            g[e] = leg_guard(x, p, tr, kin)


@model_function
def outcome_image(x, u, p, tr, continued, out):
    """The image of outcome transition record tr (its event's outcome at x), or of its
    continuation (a bounce's rest: the strike made plastic) into out; nan without outcome. Where
    the outcome at x is not tr's target (chosen where the step landed), the impact into that
    target (``friction.realize``)."""
    ev = int(p[P_EVENT]) + EVENT_SIZE * int(p[tr + TR_EVENT])
    contacts = int(p[P_NCONTACT])
    status = scratch(max(1, contacts))
    image = out[: x.shape[0]]
    found = outcome(x, u, p, ev, continued, status, image)
    if found and not continued and status_code(status, contacts) != p[tr + TR_TARGET]:
        found = realize(x, p, p[tr + TR_TARGET], image)
    if not found:
        image[:] = math.nan
