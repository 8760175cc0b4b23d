"""The terrain's height h(x), slope dh/dx and curvature d2h/dx2 as model functions over its
encoding (``legsim.terrain`` describes the kinds and their arrays): a leaf module, so that the
compiled code of the model functions that read the terrain does not depend on how a scene's
``[terrain]`` table is read.
"""

from __future__ import annotations

import math

from .compiled.functions import model_function

FLAT, SLOPE, PROFILE, SINE = 0.0, 1.0, 2.0, 3.0
#: How near a profile's breakpoint (m) a moving point takes the face it moves onto
#: (``face_slope``): above the rounding to which the loop locates an event at a corner (the
#: point's x then lies within an ulp or so of the breakpoint, on either side, 1e-13 m at a
#: kilometre), and so small that the event it moves is not moved measurably.
CORNER_RESOLUTION = 1e-12
#: How near a concave breakpoint (m) a stuck point sits in its notch, held by both faces
#: (``notch``): above the drift of a stuck point over a stance (about a micrometre), below the
#: strips the method resolves.
NOTCH_RESOLUTION = 1e-5


@model_function
def _segment(p, at, x):
    """Index i of the profile segment [x_i, x_{i+1}) holding x (bisection); -1 left of x_0, n - 1
    at or right of x_{n-1}."""
    n = int(p[at + 1])
    xs = at + 2
    if x < p[xs]:
        return -1
    if x >= p[xs + n - 1]:
        return n - 1
    lo, hi = 0, n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if p[xs + mid] <= x:
            lo = mid
        else:
            hi = mid
    return lo


@model_function
def height(p, at, x):
    """h(x) (m) of the terrain encoded at p[at:]."""
    kind = p[at]
    if kind == FLAT:
        return p[at + 1]
    if kind == SLOPE:
        return p[at + 3] + p[at + 1] * (x - p[at + 2])
    if kind == SINE:
        return p[at + 1] + p[at + 2] * math.sin(p[at + 3] * x + p[at + 4])
    n = int(p[at + 1])
    xs, zs = at + 2, at + 2 + n
    i = _segment(p, at, x)
    if i < 0:
        return p[zs]
    if i >= n - 1:
        return p[zs + n - 1]
    w = (x - p[xs + i]) / (p[xs + i + 1] - p[xs + i])
    return p[zs + i] + w * (p[zs + i + 1] - p[zs + i])


@model_function
def slope(p, at, x):
    """dh/dx at x of the terrain encoded at p[at:] (the right segment's at a breakpoint)."""
    kind = p[at]
    if kind == FLAT:
        return 0.0
    if kind == SLOPE:
        return p[at + 1]
    if kind == SINE:
        return p[at + 2] * p[at + 3] * math.cos(p[at + 3] * x + p[at + 4])
    return _segment_slope(p, at, _segment(p, at, x))


@model_function
def heights_along(p, at, xs, out):
    """``height`` at each x of xs (k,) into out (k,): one compiled call for many points."""
    for i in range(xs.shape[0]):
        out[i] = height(p, at, xs[i])


@model_function
def slopes_along(p, at, xs, out):
    """``slope`` at each x of xs (k,) into out (k,)."""
    for i in range(xs.shape[0]):
        out[i] = slope(p, at, xs[i])


@model_function
def face_slope(p, at, x, vx):
    """dh/dx of the face under a point at x moving at vx (m/s) along x: ``slope``, but within
    ``CORNER_RESOLUTION`` of a profile's breakpoint the slope of the segment the point moves
    onto (the right one when it does not move along x). An event at a corner is located where
    the face changes, which rounding leaves on either side of the breakpoint: there the face
    the point enters decides the impact and the guards, not the one it leaves."""
    if p[at] != PROFILE or vx == 0.0:
        return slope(p, at, x)
    # a profile's slope is constant on each segment: a point a hair ahead is on the face moved onto
    return slope(p, at, x + math.copysign(CORNER_RESOLUTION, vx))


@model_function
def _segment_slope(p, at, i):
    """dh/dx of profile segment i (level left of the first point and right of the last)."""
    n = int(p[at + 1])
    if i < 0 or i >= n - 1:
        return 0.0
    xs, zs = at + 2, at + 2 + n
    return (p[zs + i + 1] - p[zs + i]) / (p[xs + i + 1] - p[xs + i])


@model_function
def notch(p, at, x):
    """(dh/dx of the bisector, half the angle between the faces' normals (rad)) of the concave
    breakpoint of a profile within ``NOTCH_RESOLUTION`` of x; (0, -1) where there is none. A
    point stuck there touches both faces: the ground can push it anywhere in the sum of their
    friction cones, which is the cone about the bisector of half-angle ``half + atan(mu)``."""
    if p[at] != PROFILE:
        return 0.0, -1.0
    n = int(p[at + 1])
    xs = at + 2
    i = _segment(p, at, x)  # the nearest breakpoint k: an end of segment i
    k = 0 if i < 0 else n - 1 if i >= n - 1 else i if x - p[xs + i] <= p[xs + i + 1] - x else i + 1
    if abs(x - p[xs + k]) > NOTCH_RESOLUTION:
        return 0.0, -1.0
    left, right = _segment_slope(p, at, k - 1), _segment_slope(p, at, k)
    if right <= left:  # level or convex
        return 0.0, -1.0
    sl, sr = math.sqrt(1.0 + left * left), math.sqrt(1.0 + right * right)
    bx, bz = -left / sl - right / sr, 1.0 / sl + 1.0 / sr
    cosine = min(1.0, (left * right + 1.0) / (sl * sr))
    return -bx / bz, 0.5 * math.acos(cosine)


#: The friction coefficient standing for a cone that is wider than a half-plane: a stuck point
#: whose faces' cones together span more than 180 degrees never slips.
UNBOUNDED_MU = 1e12


@model_function
def notch_mu(mu, half):
    """The friction coefficient about a notch's bisector (``notch``) of a contact with
    coefficient mu on each face: tan(half + atan(mu)), ``UNBOUNDED_MU`` past a half-plane; mu
    itself for a frictionless contact (mu < 0)."""
    if mu < 0.0:
        return mu
    angle = half + math.atan(mu)
    return UNBOUNDED_MU if angle >= 0.5 * math.pi - 1e-12 else math.tan(angle)


@model_function
def curvature(p, at, x):
    """d2h/dx2 (1/m) at x of the terrain encoded at p[at:] (0 but on a sine)."""
    if p[at] == SINE:
        return -p[at + 2] * p[at + 3] * p[at + 3] * math.sin(p[at + 3] * x + p[at + 4])
    return 0.0


#: Samples per wavelength in the search for a sine's point nearest a centre (``nearest``), and
#: the most samples a search takes. Where the centre lies within the terrain's least radius of
#: curvature of it, its squared distance to the terrain has a single minimum in the samples'
#: neighbourhood, which Newton's method then finds to rounding.
NEAREST_SAMPLES, NEAREST_MOST = 16, 512
NEWTON_STEPS = 12


@model_function
def _sine_foot(p, at, xc, zc):
    """x (m) of the sine's point nearest (xc, zc): the least squared distance over samples
    within the distance to the point (xc, h(xc)) above or below the centre, then Newton's method
    on its derivative, each step kept within one sample spacing."""
    reach = abs(zc - height(p, at, xc))
    if reach == 0.0:
        return xc
    wavelengths = 2.0 * reach * p[at + 3] / (2.0 * math.pi)
    count = int(min(NEAREST_MOST, math.ceil(NEAREST_SAMPLES * wavelengths) + 3))
    spacing = 2.0 * reach / (count - 1)
    best, least = xc, math.inf
    for i in range(count):
        s = xc - reach + i * spacing
        dz = height(p, at, s) - zc
        value = (s - xc) * (s - xc) + dz * dz
        if value < least:
            best, least = s, value
    s = best
    for _ in range(NEWTON_STEPS):
        dz = height(p, at, s) - zc
        g = slope(p, at, s)
        first = (s - xc) + dz * g
        second = 1.0 + g * g + dz * curvature(p, at, s)
        step = first / second if second > 0.0 else first
        step = max(-spacing, min(spacing, step))
        s -= step
        if abs(step) <= 1e-15 * (1.0 + abs(s)):
            break
    return s


#: How much the slope must fall across a profile's breakpoint for a ball to roll round it on an
#: arc (a convex corner): collinear points, whose slopes agree to rounding, are a face.
CONVEX_SLOPES = 1e-9


@model_function
def _piece_foot(p, at, i, xc, zc):
    """(x, z, breakpoint) of the point of profile piece i nearest (xc, zc): the segment
    [x_i, x_{i+1}], or for i = -1 and i = n - 1 the level rays left of x_0 and right of x_{n-1};
    breakpoint k where the projection is clamped to breakpoint k, else -1 (inside the piece)."""
    n = int(p[at + 1])
    xs, zs = at + 2, at + 2 + n
    if i < 0:
        return min(xc, p[xs]), p[zs], 0 if xc >= p[xs] else -1
    if i >= n - 1:
        return max(xc, p[xs + n - 1]), p[zs + n - 1], n - 1 if xc <= p[xs + n - 1] else -1
    ax, az, bx, bz = p[xs + i], p[zs + i], p[xs + i + 1], p[zs + i + 1]
    w = ((xc - ax) * (bx - ax) + (zc - az) * (bz - az)) / ((bx - ax) * (bx - ax) + (bz - az) * (bz - az))
    if w <= 0.0:
        return ax, az, i
    if w >= 1.0:
        return bx, bz, i + 1
    return ax + w * (bx - ax), az + w * (bz - az), -1


@model_function
def _convex(p, at, k):
    """Whether profile breakpoint k is a convex corner (the slope falls across it)."""
    left, right = _segment_slope(p, at, k - 1), _segment_slope(p, at, k)
    return left - right > CONVEX_SLOPES * (1.0 + abs(left) + abs(right))


@model_function
def _foot_grade(p, at, i, k, fx, fz, xc, zc):
    """The slope g of the normal (-g, 1) at the foot (fx, fz) of piece i (breakpoint k, -1 inside
    it) seen from (xc, zc): the face's, or at a convex corner the line from it to the centre's;
    nan at a corner level with or above the centre (no normal of that form)."""
    if k < 0:
        return _segment_slope(p, at, i)
    if not _convex(p, at, k):
        return face_slope(p, at, fx, xc - fx)
    if zc <= fz:
        return math.nan
    return -(xc - fx) / (zc - fz)


@model_function
def _window(p, at, xc, zc):
    """The first and last profile pieces that can hold the point nearest (xc, zc): the point
    (xc, h(xc)) is on the terrain, so the nearest lies within |zc - h(xc)| of xc along x."""
    reach = abs(zc - height(p, at, xc))
    return _segment(p, at, xc - reach), _segment(p, at, xc + reach)


@model_function
def _profile_nearest(p, at, xc, zc):
    """``nearest`` on a profile: the least distance over its pieces within reach of the centre
    (``_window``); a tie goes to a face, and a breakpoint that is not a convex corner is a face's end. On a
    face the normal is the face's and k = 0; at a convex corner (one the centre lies beyond
    both faces of) the normal points from the corner to the centre, and the level set through
    the centre is the circle of radius d about the corner: k = 1 / d. At a concave corner the
    nearest face changes where the centre crosses the bisector, a jump of the normal that the
    bridge's corner event takes as a strike on the new face. A centre below the terrain, or level
    with or below the corner it is nearest to (past the model's range: deep in the ground), takes
    the face at that corner it lies towards, k = 0."""
    first, last = _window(p, at, xc, zc)
    best_i, best_x, best_z, best_k, least = -1, xc, zc, -1, math.inf
    for i in range(first, last + 1):
        fx, fz, k = _piece_foot(p, at, i, xc, zc)
        squared = (fx - xc) * (fx - xc) + (fz - zc) * (fz - zc)
        if squared < least or (squared == least and k < 0 <= best_k):
            best_i, best_x, best_z, best_k, least = i, fx, fz, k, squared
    above = 1.0 if zc >= height(p, at, xc) else -1.0
    d = above * math.sqrt(least)
    if best_k >= 0 and _convex(p, at, best_k) and above > 0.0 and zc > best_z and least > 0.0:
        return best_x, d, _foot_grade(p, at, best_i, best_k, best_x, best_z, xc, zc), 1.0 / d
    g = face_slope(p, at, best_x, xc - best_x) if best_k >= 0 else _segment_slope(p, at, best_i)
    return best_x, d, g, 0.0


@model_function
def second_contact(p, at, xc, zc, within):
    """The slope g of the normal (-g, 1) at a second point of the profile that (xc, zc) lies within
    ``within`` (m) of the distance to its nearest point: another face, or a convex corner, that
    a ball there touches besides its nearest point (in a notch, across a pit narrower than
    itself); nan where there is none (and on other terrains)."""
    if p[at] != PROFILE:
        return math.nan
    s, distance, _, _ = _profile_nearest(p, at, xc, zc)
    sz = height(p, at, s)
    first, last = _window(p, at, xc, zc)
    least, grade = math.inf, math.nan
    for i in range(first, last + 1):
        fx, fz, k = _piece_foot(p, at, i, xc, zc)
        if abs(fx - s) <= CORNER_RESOLUTION and abs(fz - sz) <= CORNER_RESOLUTION:
            continue  # the nearest point itself
        if k >= 0 and not _convex(p, at, k):
            continue  # a face's end at a notch: the faces are the contacts there
        squared = (fx - xc) * (fx - xc) + (fz - zc) * (fz - zc)
        if squared < least:
            least, grade = squared, _foot_grade(p, at, i, k, fx, fz, xc, zc)
    return grade if math.sqrt(least) <= abs(distance) + within else math.nan


@model_function
def nearest(p, at, xc, zc):
    """(s, d, g, k): the terrain's point (s, h(s)) nearest the point (xc, zc) (m, a round
    contact's centre), its signed distance d (m) along the terrain's normal n = (-g, 1) /
    sqrt(1 + g^2) there (> 0 above the terrain), the slope g = h'(s), and the curvature k (1/m)
    of the level set {distance = d} through the centre: -kappa / (1 - kappa d), kappa =
    h''(s) / (1 + g^2)^1.5 (> 0 where the terrain bulges towards the centre, whose distance then
    grows as k (t . v)^2 beyond its acceleration along n). On a profile, a face or a convex
    corner (``_profile_nearest``)."""
    kind = p[at]
    if kind == PROFILE:
        return _profile_nearest(p, at, xc, zc)
    s = _sine_foot(p, at, xc, zc) if kind == SINE else xc
    g = slope(p, at, s)
    norm = math.sqrt(1.0 + g * g)
    d = (zc - height(p, at, s) - g * (xc - s)) / norm
    if kind == SLOPE:  # the foot of the perpendicular, which the loop over samples need not find
        s = xc + g * d / norm
        d = (zc - height(p, at, s) - g * (xc - s)) / norm
    kappa = curvature(p, at, s) / (norm * norm * norm)
    return s, d, g, -kappa / (1.0 - kappa * d)


@model_function
def nearest_along(p, at, xs, zs, out):
    """``nearest`` at each point (xs[i], zs[i]) (k,) into out (k, 4): one compiled call for many."""
    for i in range(xs.shape[0]):
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = nearest(p, at, xs[i], zs[i])
