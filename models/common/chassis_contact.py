"""Vehicle contact of the 3D models (multibody's numba time loop, exudyn's loads): chassis superellipsoids
against each other and against rigid box barriers; continuous normal force, by default from the vehicles'
crush structures (docs/physics.md §13a, crush_structure.py: the CRASH3 line B C per unit of engaged width, the
struck sides in series, unloading to the restitution, crush memory per pair; integrated over the crush profile
across the engaged width, profile_force), else the generic Hertz-type
force with hysteresis damping (LAW_GENERIC, below); friction.
Also the packing of the contact arrays both models hand to `contacts`
(`pair_table`, `barrier_rows`, `contact_arrays`); what a run's contacts report after it: contact_report.py.

Geometry. Each vehicle's chassis is one superellipsoid (shape row CSH[v] = [a, b, c, eps1, eps2, x_off,
z_off], centred at x_off, z_off in the chassis frame); a barrier is a rigid box (BOXR centre, BOXA
rotation, BOXE half-extents). The contact normal is searched among HORIZONTAL directions
d = (cos th, sin th, 0) only: the signed gap is g = max_th -(h1(d) + h2(-d)) (h = global support
functions, closed form: narrow_phase.support_value_body), i.e.
the separating-axis gap of the two bodies' plan shadows. Why horizontal only: the chassis slabs are
0.5 m tall and a car-to-car crush reaches 0.5-1 m with the literature stiffness of docs/physics.md §27, so the
3D minimum-translation distance would flip to a vertical push-out at deep penetration (a vehicle is not
pushed over the other); vehicles crush horizontally. A vertical gate (the z-ranges must overlap) keeps
vehicles at different heights apart. The 1D maximisation over th is a golden-section search: warm-started
(+-0.15 rad window, re-centred when the optimum hits its edge) from the previous evaluation while a pair
is in contact (it follows the contact branch), global (72-angle scan + golden refinement) otherwise
(narrow_phase.horizontal_gap).
Contact point: in plan, the midpoint of the two support points sigma1(d), sigma2(-d) (for a box: of sigma1(d)
and its projection on the box face); its height the middle of the band where the two bodies' z-ranges overlap
(§13a "point's height"). No Newton / SLSQP is needed in the loop (narrow_phase.py stays the general 3D tool and
its tests).

Engagement (structure law, §13a): from the first touch the normal is the bisector of the two struck faces'
outward normals (crush_structure.engagement_normal; a barrier's face alone; two upright vehicles' faces from their
approach, crush_structure.swept_faces, §13a "Struck faces"), turning with the vehicles, and the
crush is the two shapes' projection overlap along it counted from the episode's first touch (PST[:, S_C0]), at
least their overlap -g, and kept continuous within an episode (S_CI, S_CR, S_CM); the point lies on the line of
action of that crush's gradient, midway between the two support points across the normal, so that the force does
no work around a closed path ("Work of the engaged force"). The gap search above still decides whether the shapes
overlap at all.

Generic law. Force on vehicle i (the body 1 of the pair, d points from i to j), penetration delta = -g > 0,
delta_dot = (v_i(M) - v_j(M)).d (> 0 approaching):
    F_N = K delta^n (1 + chi delta_dot / delta_dot0),  F_N >= 0   (contact_force.normal_force_chi)
    F_T = -mu c(|v_T|) F_N v_T/|v_T|                               (contact_force.friction_ratio_code)
    F_i = -F_N d + F_T at M on the chassis of i, F_j = -F_i on j (a barrier takes its share).
delta_dot0 is the approach velocity stored at the touch (PST[:, S_DDT]: the episode's onset, or a re-touch's
own after its contact ended within the episode) while the pair is in contact; for a pair not in contact (only
within the integrator's trial stages, delta <= onset tolerance) the current delta_dot is used.
"""
import math

import numpy as np
from numba import njit

from crashlab.models.common.restitution_law import speed_restitution

from .broad_phase import obb_overlap
from .contact_force import friction_ratio_code, normal_force_chi
from .crush_structure import (
    E_HI,
    E_LO,
    N_STR,
    engagement_normal,
    face_code,
    permanent_crush,
    push_damping,
    series_stiffness,
    strip_force,
    structure_slot,
    swept_faces,
)
from .narrow_phase import horizontal_gap, support_value_body
from .rotations import rot_z, rotation_matrix_into
from .superellipsoid import support_global, support_local

# pair parameters PP[p]: i, j (j >= nv: barrier j - nv), K of the generic law, the structure rows
# (crush_structure.structure_row: A, B, width of front, rear, side) of i and of j (zeros for a barrier: rigid), the
# pair's reduced mass (the push damping's, §13a)
P_I, P_J, P_K, P_STR_I, P_STR_J, P_MEFF = 0, 1, 2, 3, 3 + N_STR, 3 + 2 * N_STR
N_PP = 4 + 2 * N_STR
# chassis contact laws (the model option contact_law): the vehicles' crush structure (§13a), the generic
# Hertz-type stiffness K with the scene's force_law (§13)
LAW_STRUCTURE, LAW_GENERIC = 0, 1
CONTACT_LAWS = ("structure", "generic")
# pair state PST[p]: warm angle and its validity, active flag, approach velocity stored at onset; the open
# episode's bookkeeping (contact_episodes.py): onset time, impulse (3), peak normal force, max penetration,
# work, point and normal angle at the peak force, velocities (vx, vy, yaw rate) of i and j at onset
(S_TH, S_THOK, S_ACT, S_DD0, S_T0, S_JX, S_JY, S_JZ, S_PEAK, S_MAXPEN, S_WORK, S_PX, S_PY, S_PTH,
 S_VI, S_VJ) = 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 17
# the pair's crush memory (structure law, kept across its episodes): largest crush, struck sides of i and j
# (crush_structure.face_code) latched while the pair is not in contact; a new contact on other sides forgets it
# (the generic law sets the sides at each episode's first touch: they share its energy in the impact rows, §21)
S_CMAX, S_SIDE_I, S_SIDE_J = 20, 21, 22
# restitution = "speed" (cfg_e = crashlab.restitution.E_SPEED_LAW): the unloading's e, set from the law at the
# normal closing speed S_VCLOSE of the pair's first crush (while S_CMAX is 0) and kept for it (docs/physics.md §13b)
S_E, S_VCLOSE = 23, 24
# engagement (structure law, §13a): the struck faces of i and j (crush_structure.face_code; latched with the sides;
# a barrier's own face, where S_SIDE_J is 0), and the crush offset along their engagement normal at the first
# touch (-1: not engaged, the minimum-translation normal is used)
S_FACE_I, S_FACE_J, S_C0 = 25, 26, 27
# the crush of an open episode kept continuous (structure law, §13a "Work of the engaged force"): S_CI the crush at
# the last accepted evaluation, S_CR the geometric measure there and S_CM which one (2 the engagement normal's, 1 the
# minimum-translation overlap, 0 none yet: the geometric crush is used); an evaluation adds the measure's change
# since, none where the measure has switched (contact_episodes.track_peak keeps them)
S_CI, S_CR, S_CM = 28, 29, 30
# an episode whose contact has ended while the pair is not yet SEPARATION apart (S_ACT = 2, contact_episodes.py): its
# end (time, normal velocity, the velocities (vx, vy, yaw rate) of i and j there), and whether the open episode is
# a push (contact later than PUSH_TIME after its impact; crashlab.outcome, docs/physics.md §15)
S_T1, S_DD1, S_VEI, S_VEJ, S_PUSH = 31, 32, 33, 36, 39
# a pair's episode state PST[p, S_ACT]: NONE, IN_CONTACT, or ENDED: its contact has ended but the pair is not yet
# SEPARATION apart, a re-touch continues the episode (contact_episodes.py; docs/physics.md §15 "Episodes and pushes")
NONE, IN_CONTACT, ENDED = 0.0, 1.0, 2.0
# the approach velocity of the episode's current touch (generic law's delta_dot0): S_DD0 at onset, a re-touch's own
# after an ENDED contact (contact_episodes.episode_step); S_DD0 stays the episode's (its impact row)
S_DDT = 40
# structure law: each structure's own largest crush at the pair's deepest strip (its memory in this pair, the
# strips' less their share of the setback; §13a "Face memory": against a face crushed before, the pair's total crush
# is no longer shared as one loading shares it), reset with S_CMAX
S_CM1, S_CM2 = 41, 42
# structure law: 1 once a pair with a crush memory has been found apart with no episode open (gap >= 0, or a gate);
# its struck faces are then chosen again at its next touch, by the approach as at a first touch (§13a "Crush
# memory"); 0 after that choice. Before 2026-11-28 they were chosen while apart, by the touch point's rule, which
# differs from the approach's at rounded corners: the memory was forgotten and a re-touch met fresh structures
S_APART = 43
# structure law, the permanent-set gate (§13a "Face memory"): the pair's scalar memory alone decides that it bears
# nothing (skipping the profile) only while no strip's memory was bounded by its place's face memory at the last
# profile evaluation (S_BOUND) and the pair has since moved less than GATE_MOVE: the relative pose then (shape centre
# of j in i's frame, relative heading)
S_BOUND, S_RX, S_RY, S_RH = 44, 45, 46, 47
# a re-touch within an open episode (contact_episodes.episode_step): 1 while its contact lasts, and the episode's
# impulse (3) when it began (a graze, which carries less than GRAZE_SHARE of it, does not move the episode's end)
S_RT, S_JR = 48, 49
# structure law, the engagement's hysteresis (§13a "Engagement"): 1 where the last accepted evaluation of the open
# episode crushed along the engagement normal (ENGAGED_BAND)
S_ENG = 52
N_PST = 53
# per-stage outputs PSG[stage, p]: G_DEL is the penetration beyond the permanent crush (> 0: in contact; the
# overlap of the undeformed shapes itself for the generic law), G_CRUSH the overlap of the undeformed shapes
# (total crush), G_WIDTH the engaged width
(G_FN, G_DEL, G_FX, G_FY, G_FZ, G_POW, G_PX, G_PY, G_TH, G_DDOT, G_CRUSH, G_WIDTH) = range(12)
# structure law: the geometric crush measure of the evaluation and which one (S_CR, S_CM); the shapes' plan gap g
# (GAP_FAR where the gates found them apart)
G_RAW, G_MEAS, G_GAP = 12, 13, 14
# structure law: 1 where the evaluation crushed along the engagement normal (S_ENG at accepted evaluations)
G_ENG = 15
# structure law, the face memory's candidates (§13a "Face memory", contact_episodes.track_peak keeps them at accepted
# evaluations): G_NS strips recorded (0: none), from G_STRIP four numbers per strip: the bin of body 1's struck face
# it lies on (FM's column; -1: none), body 1's crush there, the same for body 2
G_NS, G_STRIP = 16, 17
N_PSG_HEAD = 17
GAP_FAR = 1.0
# broad-phase counters BPC: pair evaluations, removed by the plan bounding circles, by the height ranges,
# by the oriented boxes (15-axis SAT), and those that reach the gap search (narrow phase)
B_PAIRS, B_CIRCLE, B_HEIGHT, B_OBB, B_NARROW = range(5)
N_BPC = 5
# barrier: a rigid box standing on the road, 1.5 m tall
BARRIER_HALF_HEIGHT = 0.75
# crush profile (structure law, §13a "Engaged width"): each body's plan outline as N_OUT vertices in its own frame
# about its shape centre (a vehicle's superellipse at the outward normal angles 2 pi k / N_OUT, so they crowd where
# it is curved; a barrier's four corners, the last repeated), the engaged width cut into N_STRIP strips
N_OUT, N_STRIP = 64, 24
# after the strips' records, each structure's own crush at the deepest bearing strip with its share of that strip's
# setback added back (the pair's own memory S_CM1, S_CM2 candidates: contact_episodes.remember_strips)
G_OWN = G_STRIP + 4 * N_STRIP
N_PSG = G_OWN + 2
# m: in an open episode an engaged pair stays engaged while its crush along the engagement normal is at most this
# below the shapes' overlap, and a pair on the overlap's normal engages once it is this above (§13a "Engagement"):
# at equality the normal flipped between the two measures' on round-off, 65 deg apart (a saloon pushing a locked
# Clio at rest: exudyn's load iteration never settled); 1 mm moves a structure's force by at most w B 1 mm (1.5 kN
# for a saloon's front)
ENGAGED_BAND = 1e-3
# face memory FM[v] (§13a "Face memory"): each vehicle's own largest crush along each struck face (front, rear,
# left, right, roof, underbody: crush_structure.face_code) in N_FACE_BIN bins across it (front and rear across the
# width, the others along the length), kept for the run and shared by every partner: first what every strip on a
# bin has reached (its least crush), from FM_ANY what any strip on it has (its largest: where a place on the car
# was never crushed, the pair's own memory does not hold, §13a "Face memory")
N_FACES, N_FACE_BIN = 6, 32
FM_ANY = N_FACES * N_FACE_BIN
N_FM = 2 * FM_ANY
# m: a face memory counts where it exceeds the pair's own by more than this (its resolution: the bins' width times
# the profile's slope, the chord between the bins' centres); below, the pair's own memory is exact and the face's
# representation error made strips reload on their steep unloading line (the side collision 939 steps against
# 808; RICSAC 2's delta-V moved with the number of bins, 16 / 32 / 64)
FACE_MEMORY_TOL = 0.03
# a tilted vehicle's outline (§13a "A tilted body"): its z = 0 section (the cached N_OUT-gon) up to COS_SECTION of
# tilt (the angle of its up axis from the vertical, or from the downward one), its shadow on the road (the 3D
# support points along the horizontal directions) from COS_SHADOW, the force blended between (10-20 deg)
COS_SECTION, COS_SHADOW = math.cos(math.radians(10.0)), math.cos(math.radians(20.0))
# m: the permanent-set gate's reach (S_BOUND): a third of FACE_MEMORY_TOL, the face memory's resolution, of relative
# motion of any point of the pair (its places on the faces move less than that) before the profile is looked at again
GATE_MOVE = FACE_MEMORY_TOL / 3.0


@njit(cache=True)
def chassis_pose(y, nq, A):
    """Chassis (body 0) rotation into A, returns (r, v, omega_global) as tuples."""
    rotation_matrix_into(y[3], y[4], y[5], y[6], A)
    w0, w1, w2 = y[nq + 3], y[nq + 4], y[nq + 5]
    om = (A[0, 0] * w0 + A[0, 1] * w1 + A[0, 2] * w2, A[1, 0] * w0 + A[1, 1] * w1 + A[1, 2] * w2,
          A[2, 0] * w0 + A[2, 1] * w1 + A[2, 2] * w2)
    return (y[0], y[1], y[2]), (y[nq], y[nq + 1], y[nq + 2]), om


@njit(cache=True, inline="always")
def _point_velocity(r, v, om, M):
    """Velocity of the body point M (CG r, velocity v, angular velocity om): v + om x (M - r)."""
    a = (M[0] - r[0], M[1] - r[1], M[2] - r[2])
    return (v[0] + om[1] * a[2] - om[2] * a[1], v[1] + om[2] * a[0] - om[0] * a[2],
            v[2] + om[0] * a[1] - om[1] * a[0])


@njit(cache=True, inline="always")
def _struck_face(A, rc, M, sh, box):
    """The struck face (crush_structure.face_code) of the point M on a body of rotation A, shape centre rc, shape
    row sh (half length, width, height first): a tilted vehicle's roof or underbody too, a barrier box (box True)
    one of its four upright faces."""
    xl = A[0, 0] * (M[0] - rc[0]) + A[1, 0] * (M[1] - rc[1]) + A[2, 0] * (M[2] - rc[2])
    yl = A[0, 1] * (M[0] - rc[0]) + A[1, 1] * (M[1] - rc[1]) + A[2, 1] * (M[2] - rc[2])
    zl = A[0, 2] * (M[0] - rc[0]) + A[1, 2] * (M[1] - rc[1]) + A[2, 2] * (M[2] - rc[2])
    return face_code(xl, yl, zl, sh[0], sh[1], 0.0 if box else sh[2])


@njit(cache=True)
def _struck_faces(A1, rc1, sh1, r1, v1, om1, A2, rc2, sh2, r2, v2, om2, k2, M, g):
    """The struck faces (crush_structure.face_code) of a pair at its first touch at M (gap g < 0): for an upright
    vehicle and an upright vehicle or a barrier those of their approach (crush_structure.swept_faces, §13a "Struck
    faces"), else (a tilted body's roof or underbody, no approach) and before the touch each body's face nearest M
    in proportion."""
    fi = _struck_face(A1, rc1, M, sh1, False)
    fj = _struck_face(A2, rc2, M, sh2, k2 == 1)
    if g >= 0.0 or fi > 3 or fj > 3:
        return fi, fj
    u1 = _point_velocity(r1, v1, om1, M)
    u2 = _point_velocity(r2, v2, om2, M)
    h1, h2 = math.hypot(A1[0, 0], A1[1, 0]), math.hypot(A2[0, 0], A2[1, 0])
    if h1 < 0.5 or h2 < 0.5:  # a body pitched past 60 deg: no plan heading
        return fi, fj
    si, sj, ok = swept_faces(rc2[0] - rc1[0], rc2[1] - rc1[1], u2[0] - u1[0], u2[1] - u1[1], A1[0, 0] / h1,
                             A1[1, 0] / h1, sh1[0], sh1[1], A2[0, 0] / h2, A2[1, 0] / h2, sh2[0], sh2[1])
    return (si, sj) if ok else (fi, fj)


@njit(cache=True)
def _wrap(x):
    """x wrapped to [-pi, pi)."""
    return (x + math.pi) % (2.0 * math.pi) - math.pi


@njit(cache=True)
def _height(U, S, m, u):
    """The largest height S of the chain (U, S) of m vertices at the lateral coordinate u; -inf where it does not
    reach u."""
    h = -math.inf
    for e in range(m - 1):
        u0, s0, u1, s1 = U[e], S[e], U[e + 1], S[e + 1]
        if u0 > u1:
            u0, s0, u1, s1 = u1, s1, u0, s0
        if u0 <= u <= u1:
            h = max(h, s0 if u1 - u0 <= 1e-12 else s0 + (s1 - s0) * (u - u0) / (u1 - u0))
    return h


@njit(cache=True)
def _ends(U, m):
    """Indices of the least and the largest of U[:m]."""
    i = j = 0
    for q in range(1, m):
        if U[q] < U[i]:
            i = q
        if U[q] > U[j]:
            j = q
    return i, j


@njit(cache=True)
def _facing_chain(O, box, A, rc, n0, n1, sign, U, S):
    """The part of the plan outline O (vertices in the body frame about the shape centre rc, plan rotation from A)
    that faces sign n, n = (n0, n1): its vertices' lateral coordinates U = p . t (t = (-n1, n0)) and heights
    S = sign (p . n), in order along the outline; returns their number. A vehicle's vertex k has the outward
    normal angle 2 pi k / N_OUT (plan_outline), so only the arc between the extremes across n is taken: the vertices
    whose normals lie between those of the support points along -t and +t in the body frame (the plan block M of A
    maps body to plane, so those normals are along M^T (-t), M^T t: 90 deg either side of sign n's for an upright
    body, not for a pitched or rolled one), one beyond each end; a box (box True) is its first four vertices."""
    if box:
        k0, m = 0, 4
    else:
        step = 2.0 * math.pi / N_OUT
        alpha = math.atan2(sign * (A[0, 1] * n0 + A[1, 1] * n1), sign * (A[0, 0] * n0 + A[1, 0] * n1))
        tb0, tb1 = A[0, 0] * -n1 + A[1, 0] * n0, A[0, 1] * -n1 + A[1, 1] * n0  # M^T t
        b1 = alpha + _wrap(math.atan2(tb1, tb0) - alpha)
        b2 = alpha + _wrap(math.atan2(-tb1, -tb0) - alpha)
        k0 = int(math.floor(min(b1, b2) / step))
        m = int(math.ceil(max(b1, b2) / step)) - k0 + 1
    for q in range(m):
        k = (k0 + q) % O.shape[0] if not box else q
        px = rc[0] + A[0, 0] * O[k, 0] + A[0, 1] * O[k, 1]
        py = rc[1] + A[1, 0] * O[k, 0] + A[1, 1] * O[k, 1]
        U[q], S[q] = -n1 * px + n0 * py, sign * (n0 * px + n1 * py)
    if box:  # close the box
        U[4], S[4] = U[0], S[0]
        m = 5
    return m


@njit(cache=True)
def _sections(U, S, m, lo, du, out):
    """out[k]: the largest height S along the middle line of strip k, u = lo + (k + 1/2) du, of the chain (U, S)
    of m vertices (_facing_chain); -inf where it does not reach the strip. Each edge is interpolated at the strip
    lines it spans."""
    ns = out.shape[0]
    for k in range(ns):
        out[k] = -math.inf
    for e in range(m - 1):
        u0, s0, u1, s1 = U[e], S[e], U[e + 1], S[e + 1]
        if u0 > u1:
            u0, s0, u1, s1 = u1, s1, u0, s0
        if u1 - u0 > 1e-12:
            k0 = max(0, int(math.ceil((u0 - lo) / du - 0.5)))
            k1 = min(ns - 1, int(math.floor((u1 - lo) / du - 0.5)))
            for k in range(k0, k1 + 1):
                s = s0 + (s1 - s0) * (lo + (k + 0.5) * du - u0) / (u1 - u0)
                if s > out[k]:
                    out[k] = s


@njit(cache=True)
def _shadow_chain(sh, A, rc, n0, n1, sign, U, S):
    """The part of the body's shadow on the road (its outline seen from above, docs/physics.md §13a "A tilted
    body") that faces sign n: the 3D support points (superellipsoid sh, centre rc, rotation A) along the horizontal
    directions at the normal angles of sign n -90 ... +90 deg in steps of 2 pi / N_OUT, the first and the last the
    extremes across n; their U = p . t and S = sign (p . n) as _facing_chain's. Returns their number."""
    step = 2.0 * math.pi / N_OUT
    phi0 = math.atan2(sign * n1, sign * n0)
    half = N_OUT // 4
    for q in range(2 * half + 1):
        f = phi0 + (q - half) * step
        P = support_global(math.cos(f), math.sin(f), 0.0, sh, rc, A)
        U[q], S[q] = -n1 * P[0] + n0 * P[1], sign * (n0 * P[0] + n1 * P[1])
    return 2 * half + 1


@njit(cache=True)
def shadow_weight(A):
    """How much of a vehicle's outline is its shadow rather than its z = 0 section (§13a "A tilted body"): 0 up to
    10 deg of tilt (from upright or upside down), 1 from 20 deg, linear in the cosine between."""
    c = abs(A[2, 2])
    return min(max((COS_SECTION - c) / (COS_SECTION - COS_SHADOW), 0.0), 1.0)


@njit(cache=True)
def profile_force(O1, sh1, A1, rc1, O2, sh2, box2, A2, rc2, n0, n1, crush, cm, e, b1, b2, w1, w2, work):
    """profile_force_memory of one pair's memory cm (shared as its loading shares it) without face memories:
    (force, engaged width, loading line's force)."""
    none = np.zeros(0)
    share1 = b2 / (b1 + b2) if b2 > 0.0 else 1.0
    f, w, fl, _, _ = profile_force_memory(O1, sh1, A1, rc1, O2, sh2, box2, A2, rc2, n0, n1, crush, cm, share1 * cm,
                                          (1.0 - share1) * cm, e, b1, b2, w1, w2, work, none, none, -1, -1, none)
    return f, w, fl


@njit(cache=True)
def profile_force_memory(O1, sh1, A1, rc1, O2, sh2, box2, A2, rc2, n0, n1, crush, cm, cm1, cm2, e, b1, b2, w1, w2,
                         work, FM1, FM2, f1, f2, rec):
    """Normal force of the structure law over the crush profile (docs/physics.md §13a "Engaged width"): the
    engaged width (the overlap of the two plan outlines across the normal n, from body 1 towards body 2; body 2 a
    barrier's box if box2) cut into strips, each strip's local overlap along n from the outlines, its setback
    sig_k below the deepest local overlap (of the strips' middles, the width's ends and a box's corners), and the
    force per unit width of the strip's own crush,
    sum_k du strip_force(crush - sig_k, m1_k, m2_k, e, b1, b2) (CRASH3's integral over the profile; a flat
    face, sig = 0, gives w structure_force(crush, ...)), each structure's memory m_q,k at the strip the larger of
    its own in the pair (cm1, cm2: its largest crush at the pair's deepest strip, less its share of the strip's
    setback, shared as the loading shares it) and its face memory less FACE_MEMORY_TOL
    (FM1, FM2, §13a "Face memory": the vehicles' rows, the struck faces f1, f2; empty: none, a barrier's) where the
    strip lies on the face; the width at most each structure's (w1, w2; w2 <= 0: a barrier, unlimited), by scaling.
    rec (empty: not recorded): the strips' face bins and crushes (G_STRIP's four numbers per strip) for the face
    memory. A vehicle's outline is its cached z = 0 section O (sh its superellipsoid),
    or for a tilted one its shadow, the force and width blended between by the more tilted vehicle's
    shadow_weight (§13a "A tilted body"). work: (6, N_OUT + 2) scratch (the two chains, then the two strips'
    rows). Returns (force, engaged width, the force of the loading line at this crush, for the push damping's limit,
    §13a "Push damping", the pair's crush where its first strip bears: min_k sig_k + (m1_k + m2_k)(1 - e^2), the
    scalar permanent_crush(cm, e) of the pair's largest crush cm where no strip is engaged, whether a strip's memory
    was bounded by its place's face memory: the pair's own held for a place that never crushed as deep)."""
    lam = max(shadow_weight(A1), 0.0 if box2 else shadow_weight(A2))
    U1, S1, U2, S2 = work[0], work[1], work[2], work[3]
    f = w = fl = 0.0
    cp = math.inf
    bound = False
    if lam < 1.0:
        m1 = _facing_chain(O1, False, A1, rc1, n0, n1, 1.0, U1, S1)
        m2 = _facing_chain(O2, box2, A2, rc2, n0, n1, -1.0, U2, S2)
        f, w, fl, cp, bound = _chain_force(U1, S1, m1, U2, S2, m2, box2, crush, cm1, cm2, e, b1, b2, w1, w2, work[4],
                                           work[5], n0, n1, sh1, A1, rc1, sh2, A2, rc2, FM1, FM2, f1, f2,
                                           rec if lam < 0.5 else rec[:0])
    if lam > 0.0:
        m1 = _shadow_chain(sh1, A1, rc1, n0, n1, 1.0, U1, S1)
        m2 = _facing_chain(O2, True, A2, rc2, n0, n1, -1.0, U2, S2) if box2 else \
            _shadow_chain(sh2, A2, rc2, n0, n1, -1.0, U2, S2)
        fs, ws, fls, cps, bs = _chain_force(U1, S1, m1, U2, S2, m2, box2, crush, cm1, cm2, e, b1, b2, w1, w2, work[4],
                                            work[5], n0, n1, sh1, A1, rc1, sh2, A2, rc2, FM1, FM2, f1, f2,
                                            rec if lam >= 0.5 else rec[:0])
        f, w, fl = (1.0 - lam) * f + lam * fs, (1.0 - lam) * w + lam * ws, (1.0 - lam) * fl + lam * fls
        cp = min(cp, cps)  # the blended force bears where either chain's does
        bound = bound or bs
    return f, w, fl, cp if cp < math.inf else permanent_crush(cm, e), bound


@njit(cache=True)
def _face_memory(FM, px, py, rc, A, sh, face):
    """The face memory (§13a "Face memory") of the plan point (px, py) on the struck face `face`
    (crush_structure.face_code) of a body with shape centre rc, rotation A, half sizes sh, from its row FM: its
    position across the face (front and rear: y over the half width, else x over the half length) in bins, the
    memory interpolated linearly between the bins' centres (continuous as a strip moves along the face: a step in
    it made multibody's steps fail), the column of the nearest bin (which the strip's crush updates), and the most
    any strip has crushed there (FM_ANY, interpolated as well: the larger of the two bins', a step as the strip
    crossed a bin's middle, left multibody's V2 yaw-rate change on NHTSA 4438 189 deg/s at its default tolerance
    against 161 at 1e-8 and exudyn's 157; each strip's crush is kept on its bin's neighbours too,
    contact_episodes.remember_faces, so both bins hold it)."""
    dx, dy = px - rc[0], py - rc[1]
    s = (A[0, 1] * dx + A[1, 1] * dy) / sh[1] if face < 2 else (A[0, 0] * dx + A[1, 0] * dy) / sh[0]
    x = min(max(0.5 * (s + 1.0) * N_FACE_BIN - 0.5, 0.0), N_FACE_BIN - 1.0)
    j = min(int(x), N_FACE_BIN - 2)
    lam = x - j
    q = face * N_FACE_BIN
    return ((1.0 - lam) * FM[q + j] + lam * FM[q + j + 1], q + int(x + 0.5),
            (1.0 - lam) * FM[FM_ANY + q + j] + lam * FM[FM_ANY + q + j + 1])


@njit(cache=True)
def _chain_force(U1, S1, m1, U2, S2, m2, box2, crush, cm1, cm2, e, b1, b2, w1, w2, top, bot, n0, n1, sh1, A1, rc1, sh2,
                 A2, rc2, FM1, FM2, f1, f2, rec):
    """profile_force_memory over the two facing chains (U1, S1) of body 1 and (U2, S2) of body 2 (m1, m2 vertices):
    (force, engaged width, loading line's force, the crush where the first strip bears (inf: no strip), whether a
    strip's memory was bounded by its face memory)."""
    i1, j1 = _ends(U1, m1)
    i2, j2 = _ends(U2, m2)
    lo, hi = max(U1[i1], U2[i2]), min(U1[j1], U2[j2])
    w = hi - lo
    if rec.shape[0] > 0:
        rec[:] = -1.0
        rec[4 * N_STRIP], rec[4 * N_STRIP + 1] = 0.0, 0.0
    if w <= 0.0:
        return 0.0, 0.0, 0.0, math.inf, False
    du = w / N_STRIP
    top, bot = top[:N_STRIP], bot[:N_STRIP]
    _sections(U1, S1, m1, lo, du, top)
    _sections(U2, S2, m2, lo, du, bot)
    cmax = -math.inf
    for k in range(N_STRIP):  # the local overlap along n top + bot (-inf where an outline does not reach the strip)
        cmax = max(cmax, top[k] + bot[k])
    # the deepest local overlap, piecewise linear between the chains' vertices, may lie between the strips'
    # middles where a face slopes across n: at an end of the width, or at a box's corner
    # (at each end one chain's extreme vertex: its own height there)
    cmax = max(cmax, S1[i1] + _height(U2, S2, m2, lo) if U1[i1] >= U2[i2] else _height(U1, S1, m1, lo) + S2[i2])
    cmax = max(cmax, S1[j1] + _height(U2, S2, m2, hi) if U1[j1] <= U2[j2] else _height(U1, S1, m1, hi) + S2[j2])
    if box2:
        for q in range(m2 - 1):
            if lo <= U2[q] <= hi:
                cmax = max(cmax, _height(U1, S1, m1, U2[q]) + S2[q])
    # each structure's share of a strip's setback (its loading's: the same force on both, crushing f / B_q), the
    # series stiffness and the compliances (once per call: the loading line is most strips' case)
    share1 = b2 / (b1 + b2) if b2 > 0.0 else 1.0
    bs, ib1, ib2 = series_stiffness(b1, b2), 1.0 / b1, 1.0 / b2 if b2 > 0.0 else 0.0
    e2 = e * e
    f = fl = 0.0
    cp = math.inf
    deepest = 0.0
    bound = False
    for k in range(N_STRIP):
        ov = top[k] + bot[k]
        if ov > -math.inf:
            sig = cmax - ov
            mem1, mem2 = max(cm1 - share1 * sig, 0.0), max(cm2 - (1.0 - share1) * sig, 0.0)
            q1 = q2 = -1
            u = lo + (k + 0.5) * du
            # the strip's point on body 1's outline: u t + top n; on body 2's: u t - bot n
            # the face memory, within its resolution FACE_MEMORY_TOL: at least what every strip on the bins
            # reached, at most what any did (the pair's own memory is measured from its deepest strip on the current
            # geometry: after the pair turns, a place never crushed would count as crushed)
            if FM1.shape[0] > 0 and f1 >= 0:
                fm, q1, fa = _face_memory(FM1, -u * n1 + top[k] * n0, u * n0 + top[k] * n1, rc1, A1, sh1, f1)
                bound = bound or mem1 > fa + FACE_MEMORY_TOL
                mem1 = max(min(mem1, fa + FACE_MEMORY_TOL), fm - FACE_MEMORY_TOL)
            if FM2.shape[0] > 0 and f2 >= 0:
                fm, q2, fa = _face_memory(FM2, -u * n1 - bot[k] * n0, u * n0 - bot[k] * n1, rc2, A2, sh2, f2)
                bound = bound or mem2 > fa + FACE_MEMORY_TOL
                mem2 = max(min(mem2, fa + FACE_MEMORY_TOL), fm - FACE_MEMORY_TOL)
            ck = crush - sig
            fk = bs * ck if ck > 0.0 else 0.0  # the loading line (series_force)
            fl += fk
            if fk >= b1 * mem1 and (b2 <= 0.0 or fk >= b2 * mem2):  # both on it (strip_force's first case)
                c1, c2 = fk * ib1, fk * ib2
            else:
                fk, c1, c2 = strip_force(ck, mem1, mem2, e, b1, b2)
            f += fk
            cp = min(cp, sig + (mem1 + (mem2 if b2 > 0.0 else 0.0)) * (1.0 - e2))
            if rec.shape[0] > 0:
                rec[4 * k], rec[4 * k + 1], rec[4 * k + 2], rec[4 * k + 3] = q1, c1, q2, c2
                if fk > 0.0 and c1 + c2 > deepest:  # each structure's own, its share of the setback added back
                    deepest = c1 + c2
                    rec[4 * N_STRIP], rec[4 * N_STRIP + 1] = c1 + share1 * sig, c2 + (1.0 - share1) * sig
    scale = min(1.0, w1 / w)
    if w2 > 0.0:
        scale = min(scale, w2 / w)
    return f * du * scale, w * scale, fl * du * scale, cp, bound


@njit(cache=True)
def _relative_pose(A1, rc1, A2, rc2):
    """The permanent-set gate's pose of a pair (S_RX, S_RY, S_RH): body 2's shape centre in body 1's plan frame and
    their relative heading."""
    rx = A1[0, 0] * (rc2[0] - rc1[0]) + A1[1, 0] * (rc2[1] - rc1[1])
    ry = A1[0, 1] * (rc2[0] - rc1[0]) + A1[1, 1] * (rc2[1] - rc1[1])
    return rx, ry, math.atan2(A2[1, 0], A2[0, 0]) - math.atan2(A1[1, 0], A1[0, 0])


@njit(cache=True)
def _gate_pose_holds(PST, p, A1, rc1, A2, rc2, reach):
    """True while pair p has moved less than GATE_MOVE since the pose kept at its last profile (a bound on any
    point's relative displacement: the shape centre's plus the relative turn times `reach`, the circle gate's, at
    least the two shapes' plan radii)."""
    rx, ry, rh = _relative_pose(A1, rc1, A2, rc2)
    return (math.hypot(rx - PST[p, S_RX], ry - PST[p, S_RY]) + abs(_wrap(rh - PST[p, S_RH])) * reach
            < GATE_MOVE)


@njit(cache=True, inline="always")
def _apart(PST, p):
    """A pair found apart with no episode open: its faces are chosen again at its next touch (S_APART)."""
    if PST[p, S_ACT] == NONE:
        PST[p, S_APART] = 1.0


@njit(cache=True)
def _zrange(kind, sh, r, A):
    return -support_value_body(kind, 0.0, 0.0, -1.0, sh, r, A), support_value_body(kind, 0.0, 0.0, 1.0, sh, r, A)


@njit(cache=True)
def contacts(Y, nq, CSH, BOXR, BOXA, BOXE, PP, PST, psg, FX, BPC, OUT, FM, cfg_n, cfg_chi, cfg_mu, cfg_fcode, cfg_v0,
             cfg_v1, cfg_vs, cfg_vmin, cfg_law, cfg_e):
    """`contacts_awake` with every vehicle awake (every pair is evaluated)."""
    contacts_awake(Y, nq, CSH, BOXR, BOXA, BOXE, PP, PST, psg, FX, BPC, OUT, FM, cfg_n, cfg_chi, cfg_mu, cfg_fcode,
                   cfg_v0, cfg_v1, cfg_vs, cfg_vmin, cfg_law, cfg_e, np.ones(0, np.bool_))


@njit(cache=True)
def contacts_awake(Y, nq, CSH, BOXR, BOXA, BOXE, PP, PST, psg, FX, BPC, OUT, FM, cfg_n, cfg_chi, cfg_mu, cfg_fcode,
                   cfg_v0, cfg_v1, cfg_vs, cfg_vmin, cfg_law, cfg_e, awake):
    """Contact forces of every pair at state Y: FX[v] = (global force, global moment about the chassis
    CG, power) on each chassis; psg[p] the pair's outputs (G_*). Updates the warm angle PST[p, S_TH].
    awake (nv flags, or empty: all awake): a pair not in contact (no episode, or one whose contact ended) whose
    vehicles both sleep (a barrier counts as asleep) is skipped (no force, psg[p, G_DEL] = -1, not counted in
    BPC): neither moves, so it cannot come into contact (the integrator wakes a vehicle only through a pair
    evaluated with it awake).
    Broad phase (§11), cheapest first: plan bounding circles (first a looser test on the chassis CGs with
    the radii grown by the shapes' offsets, before any rotation is built), height ranges, oriented boxes (a
    superellipsoid lies inside its a x b x c box; a pair in contact always reaches the gap search, which
    also measures its separation speed); BPC counts what each stage removed.
    cfg_law: LAW_STRUCTURE (the crush structures of PP, unloading to the restitution cfg_e, §13a; cfg_e < 0:
    restitution = "speed", e from the closing speed where the pair's crush began, §13b; each vehicle's face memory
    FM, read here, kept by contact_episodes.track_peak, §13a "Face memory") or
    LAW_GENERIC (K delta^n with the hysteresis cfg_chi, §13)."""
    nv = Y.shape[0]
    use_awake = awake.shape[0] > 0
    FX[:, :] = 0.0
    A1 = np.empty((3, 3))
    A2 = np.empty((3, 3))
    rc1 = np.empty(3)
    rc2 = np.empty(3)
    # profile_force's scratch, allocated at its first use in this call (most calls have no pair in contact); psg
    # only holds its place (the same array type)
    work, have_work = psg, False
    for p in range(PP.shape[0]):
        i, j = int(PP[p, P_I]), int(PP[p, P_J])
        psg[p, :N_PSG_HEAD] = 0.0
        psg[p, G_DEL] = -1.0
        psg[p, G_GAP] = GAP_FAR
        if use_awake and PST[p, S_ACT] != IN_CONTACT and not awake[i] and (j >= nv or not awake[j]):
            if PST[p, S_ACT] == NONE:  # an ended episode's pair keeps its warm start: it may still overlap
                PST[p, S_THOK] = 0.0
            continue
        BPC[B_PAIRS] += 1
        # cheap circle gate on the CGs: the shape centre lies within |(x_off, z_off)| of the CG
        sh1 = CSH[i]
        if j < nv:
            sh2 = CSH[j]
            cx2, cy2 = Y[j, 0], Y[j, 1]
            o2 = math.sqrt(sh2[5] ** 2 + sh2[6] ** 2)
        else:
            sh2 = BOXE[j - nv]
            cx2, cy2 = BOXR[j - nv, 0], BOXR[j - nv, 1]
            o2 = 0.0
        reach = (math.sqrt(sh1[0] ** 2 + sh1[1] ** 2) + math.sqrt(sh2[0] ** 2 + sh2[1] ** 2) + 0.05
                 + math.sqrt(sh1[5] ** 2 + sh1[6] ** 2) + o2)
        dx, dy = cx2 - Y[i, 0], cy2 - Y[i, 1]
        if dx * dx + dy * dy > reach * reach:
            PST[p, S_THOK] = 0.0
            _apart(PST, p)
            BPC[B_CIRCLE] += 1
            continue
        r1, v1, om1 = chassis_pose(Y[i], nq, A1)
        sh1 = CSH[i]
        for k in range(3):
            rc1[k] = r1[k] + A1[k, 0] * sh1[5] + A1[k, 2] * sh1[6]
        if j < nv:
            k2 = 0
            r2, v2, om2 = chassis_pose(Y[j], nq, A2)
            sh2 = CSH[j]
            for k in range(3):
                rc2[k] = r2[k] + A2[k, 0] * sh2[5] + A2[k, 2] * sh2[6]
            R2 = math.sqrt(sh2[0] ** 2 + sh2[1] ** 2)
        else:
            k2 = 1
            b = j - nv
            sh2 = BOXE[b]
            for k in range(3):
                rc2[k] = BOXR[b, k]
                for m in range(3):
                    A2[k, m] = BOXA[b, k, m]
            r2 = (rc2[0], rc2[1], rc2[2])
            v2 = (0.0, 0.0, 0.0)
            om2 = (0.0, 0.0, 0.0)
            R2 = math.sqrt(sh2[0] ** 2 + sh2[1] ** 2)
        # gates: plan bounding circles, vertical ranges
        R1 = math.sqrt(sh1[0] ** 2 + sh1[1] ** 2)
        dx, dy = rc2[0] - rc1[0], rc2[1] - rc1[1]
        if dx * dx + dy * dy > (R1 + R2 + 0.05) ** 2:
            PST[p, S_THOK] = 0.0
            _apart(PST, p)
            BPC[B_CIRCLE] += 1
            continue
        z1a, z1b = _zrange(0, sh1, rc1, A1)
        z2a, z2b = _zrange(k2, sh2, rc2, A2)
        if z1a > z2b or z2a > z1b:
            _apart(PST, p)
            BPC[B_HEIGHT] += 1
            continue
        if PST[p, S_ACT] == NONE and not obb_overlap(rc1, A1, sh1[:3], rc2, A2, sh2[:3]):
            PST[p, S_THOK] = 0.0
            _apart(PST, p)
            BPC[B_OBB] += 1
            continue
        BPC[B_NARROW] += 1
        # warm start while in contact, and while a crushed pair (structure law) may still overlap after it
        warm = PST[p, S_THOK] > 0.0 and (PST[p, S_ACT] != NONE or PST[p, S_CMAX] > 0.0)
        th, g = horizontal_gap(PST[p, S_TH], warm, k2, sh1, rc1, A1, sh2, rc2, A2)
        PST[p, S_TH] = th
        PST[p, S_THOK] = 1.0
        psg[p, G_TH] = th
        psg[p, G_DEL] = -g
        psg[p, G_GAP] = g
        psg[p, G_CRUSH] = -g
        d0, d1 = math.cos(th), math.sin(th)
        P1 = support_global(d0, d1, 0.0, sh1, rc1, A1)
        # the point's height: the middle of the band where the two bodies' heights overlap (the structures meet
        # only there; §13a "point's height"), for a barrier too
        zm = 0.5 * (max(z1a, z2a) + min(z1b, z2b))
        if k2 == 0:
            P2 = support_global(-d0, -d1, 0.0, sh2, rc2, A2)
            M = (0.5 * (P1[0] + P2[0]), 0.5 * (P1[1] + P2[1]), zm)
        else:
            M = (P1[0] + 0.5 * g * d0, P1[1] + 0.5 * g * d1, zm)
        crush = -g
        gd0, gd1, Mg = d0, d1, M  # the overlap's own normal and point
        if cfg_law == LAW_STRUCTURE:
            # §13a: struck sides and faces latched until the contact opens (a contact on other faces forgets the
            # crush)
            # (a crushed pair keeps them while its shapes still overlap: the crushed zones are still the ones in
            # touch; chosen again at the first touch after the shapes have separated, S_APART, by the approach)
            if g >= 0.0:
                _apart(PST, p)
            if PST[p, S_ACT] == NONE and (PST[p, S_CMAX] == 0.0 or (g < 0.0 and PST[p, S_APART] > 0.0)):
                if g < 0.0:
                    PST[p, S_APART] = 0.0
                fi, fj = _struck_faces(A1, rc1, sh1, r1, v1, om1, A2, rc2, sh2, r2, v2, om2, k2, M, g)
                si, sj = fi, fj if k2 == 0 else 0
                if si != PST[p, S_SIDE_I] or sj != PST[p, S_SIDE_J] or fi != PST[p, S_FACE_I] \
                        or fj != PST[p, S_FACE_J]:
                    PST[p, S_CMAX] = PST[p, S_CM1] = PST[p, S_CM2] = 0.0
                    PST[p, S_SIDE_I], PST[p, S_SIDE_J] = si, sj
                    PST[p, S_FACE_I], PST[p, S_FACE_J] = fi, fj
            # §13a engagement: the normal of the struck faces (turning with the vehicles), the crush counted along
            # it from the episode's first touch (S_C0 set until the contact opens, then held)
            e0, e1, ok = engagement_normal(PST[p, S_FACE_I], PST[p, S_FACE_J], A1, A2, k2 == 1)
            measure = 1.0
            # the hysteresis (§13a "Engagement"): in an open episode, an engaged pair stays engaged down to
            # ENGAGED_BAND below the overlap, a pair on the overlap's normal engages from ENGAGED_BAND above it
            band = 0.0 if PST[p, S_ACT] == NONE else ENGAGED_BAND if PST[p, S_ENG] > 0.0 else -ENGAGED_BAND
            if ok:
                top = support_value_body(0, e0, e1, 0.0, sh1, rc1, A1)
                bot = -support_value_body(k2, -e0, -e1, 0.0, sh2, rc2, A2)
                if PST[p, S_ACT] == NONE:
                    PST[p, S_C0] = top - bot + g if e0 * d0 + e1 * d1 > 0.0 else -1.0
                measure = 2.0 if PST[p, S_C0] >= 0.0 else 1.0
                if PST[p, S_C0] >= 0.0 and top - bot - PST[p, S_C0] >= -g - band:
                    psg[p, G_ENG] = 1.0
                    # engaged: the crush along the struck faces' normal; at least the overlap -g (below, where the
                    # overlap has grown across it: the shapes are not let through each other without a force)
                    crush = top - bot - PST[p, S_C0]
                    d0, d1 = e0, e1
                    psg[p, G_TH] = math.atan2(e1, e0)
                    # the point: across the normal, midway between the two bodies' support points along it (their
                    # deepest points), the line of action of the crush's gradient (§13a, "Work of the engaged
                    # force": the force does no work around a closed path); along it, midway between the faces
                    Q1 = support_global(e0, e1, 0.0, sh1, rc1, A1)
                    if k2 == 0:
                        Q2 = support_global(-e0, -e1, 0.0, sh2, rc2, A2)
                        mt = 0.5 * (-e1 * (Q1[0] + Q2[0]) + e0 * (Q1[1] + Q2[1]))
                    else:  # a rigid box does not turn: the line through the vehicle's deepest point
                        mt = -e1 * Q1[0] + e0 * Q1[1]
                    md = 0.5 * (top + bot)
                    M = (-mt * e1 + md * e0, mt * e0 + md * e1, M[2])
            # §13a, work of the engaged force: in an open episode the crush is continuous where the measure switches
            # (the engagement normal lost or regained): the crush at the last accepted evaluation plus the change
            # of the measure since, none where it has switched
            psg[p, G_RAW], psg[p, G_MEAS] = crush, measure
            if PST[p, S_ACT] != NONE and PST[p, S_CM] > 0.0:
                crush = PST[p, S_CI] + (crush - PST[p, S_CR] if measure == PST[p, S_CM] else 0.0)
            if crush < -g - (max(band, 0.0) if psg[p, G_ENG] > 0.0 else 0.0):
                # never less than the shapes' overlap -g (continuous too; an engaged pair within ENGAGED_BAND of
                # it): a crush held below it by a switch let the pair sink into each other without a force (audit
                # seed 4: 0.33 m); along its own normal
                crush, d0, d1, M = -g, gd0, gd1, Mg
                psg[p, G_TH] = th
                psg[p, G_RAW], psg[p, G_MEAS], psg[p, G_ENG] = crush, 1.0, 0.0
            psg[p, G_CRUSH] = crush
        elif PST[p, S_ACT] == NONE and g < 0.0:  # the struck sides at the first touch, which share the episode's
            # energy in its impact rows (§21)
            fi, fj = _struck_faces(A1, rc1, sh1, r1, v1, om1, A2, rc2, sh2, r2, v2, om2, k2, M, g)
            PST[p, S_SIDE_I], PST[p, S_SIDE_J] = fi, fj if k2 == 0 else 0
        a1 = (M[0] - r1[0], M[1] - r1[1], M[2] - r1[2])
        a2 = (M[0] - r2[0], M[1] - r2[1], M[2] - r2[2])
        u1 = _point_velocity(r1, v1, om1, M)
        u2 = _point_velocity(r2, v2, om2, M)
        vr = (u1[0] - u2[0], u1[1] - u2[1], u1[2] - u2[2])
        dd = vr[0] * d0 + vr[1] * d1
        psg[p, G_DDOT] = dd
        if cfg_law == LAW_STRUCTURE:
            ci = P_STR_I + 3 * structure_slot(int(PST[p, S_SIDE_I]))
            cj = P_STR_J + 3 * structure_slot(int(PST[p, S_SIDE_J]))
            b1s, b2s = PP[p, ci + 1], PP[p, cj + 1]
            cm = PST[p, S_CMAX]
            e = cfg_e
            if cfg_e < 0.0:  # the law at the closing speed where this crush began (§13b)
                if cm == 0.0:
                    PST[p, S_VCLOSE] = max(dd, 0.0)
                    PST[p, S_E] = min(max(speed_restitution(dd), E_LO), E_HI)
                e = PST[p, S_E]
            # in contact while the undeformed shapes overlap and the crush (or their overlap, which opened the
            # episode) exceeds the permanent set where the first strip bears (each strip's memories, §13a "Face
            # memory"): an engaged episode does not chatter between the two measures. The pair's scalar permanent
            # set decides alone while it holds for every strip (the permanent-set gate, S_BOUND): a strip on a place
            # never crushed as deep bears below it
            if g >= 0.0:
                continue
            cp = permanent_crush(cm, e)
            psg[p, G_DEL] = min(max(crush - cp, -g - cp), -g)
            if (psg[p, G_DEL] <= 0.0 and PST[p, S_BOUND] == 0.0
                    and _gate_pose_holds(PST, p, A1, rc1, A2, rc2, reach)):
                continue
            # over the crush profile across the engaged width, within each structure's width
            if not have_work:
                work, have_work = np.empty((6, N_OUT + 2)), True
            fn, psg[p, G_WIDTH], f_load, cp, bound = profile_force_memory(
                OUT[i], sh1, A1, rc1, OUT[j], sh2, k2 == 1, A2, rc2, d0, d1, crush, cm, PST[p, S_CM1], PST[p, S_CM2],
                e, b1s, b2s, PP[p, ci + 2], PP[p, cj + 2] if k2 == 0 else 0.0, work, FM[i],
                FM[j] if k2 == 0 else FM[i, :0], int(PST[p, S_FACE_I]), int(PST[p, S_FACE_J]) if k2 == 0 else -1,
                psg[p, G_STRIP:])
            psg[p, G_NS] = N_STRIP
            PST[p, S_BOUND] = 1.0 if bound else 0.0
            PST[p, S_RX], PST[p, S_RY], PST[p, S_RH] = _relative_pose(A1, rc1, A2, rc2)
            psg[p, G_DEL] = min(max(crush - cp, -g - cp), -g)
            if psg[p, G_DEL] <= 0.0:
                continue
            if PST[p, S_PUSH] > 0.0:  # the crushed structures pressed in a push: damped (§13a "Push damping"), the
                # damping at most the structures' force (continuous where the contact begins and ends; no pull) and
                # the force at most the loading line's at this crush (continuous where the crush passes its memory)
                fd = push_damping(dd, e, b1s, b2s, psg[p, G_WIDTH], PP[p, P_MEFF])
                fn += min(fd, fn, max(f_load - fn, 0.0)) if fd > 0.0 else max(fd, -fn)
        else:
            if g >= 0.0:
                continue
            # in contact: the current touch's approach velocity; a first touch or a re-touch of an ended
            # contact (only within trial stages) its current one
            dd0 = PST[p, S_DDT] if PST[p, S_ACT] == IN_CONTACT else max(dd, cfg_vmin)
            fn = normal_force_chi(-g, dd, dd0, PP[p, P_K], cfg_chi, cfg_n, cfg_vmin)
        vt = (vr[0] - dd * d0, vr[1] - dd * d1, vr[2])
        st = math.sqrt(vt[0] ** 2 + vt[1] ** 2 + vt[2] ** 2)
        c = 0.0
        if st > 0.0 and fn > 0.0 and cfg_mu > 0.0:
            c = cfg_mu * friction_ratio_code(int(cfg_fcode), st, cfg_v0, cfg_v1, cfg_vs) * fn / st
        F = (-fn * d0 - c * vt[0], -fn * d1 - c * vt[1], -c * vt[2])
        # on vehicle i: F at M; on j: -F at M
        FX[i, 0] += F[0]
        FX[i, 1] += F[1]
        FX[i, 2] += F[2]
        FX[i, 3] += a1[1] * F[2] - a1[2] * F[1]
        FX[i, 4] += a1[2] * F[0] - a1[0] * F[2]
        FX[i, 5] += a1[0] * F[1] - a1[1] * F[0]
        FX[i, 6] += F[0] * u1[0] + F[1] * u1[1] + F[2] * u1[2]
        if j < nv:
            FX[j, 0] -= F[0]
            FX[j, 1] -= F[1]
            FX[j, 2] -= F[2]
            FX[j, 3] -= a2[1] * F[2] - a2[2] * F[1]
            FX[j, 4] -= a2[2] * F[0] - a2[0] * F[2]
            FX[j, 5] -= a2[0] * F[1] - a2[1] * F[0]
            FX[j, 6] -= F[0] * u2[0] + F[1] * u2[1] + F[2] * u2[2]
        psg[p, G_FN] = fn
        psg[p, G_FX], psg[p, G_FY], psg[p, G_FZ] = F[0], F[1], F[2]
        psg[p, G_POW] = F[0] * vr[0] + F[1] * vr[1] + F[2] * vr[2]
        psg[p, G_PX], psg[p, G_PY] = M[0], M[1]


# ----------------------------------------------------------------------------------------------------
# packing (Python, once per run)
# ----------------------------------------------------------------------------------------------------
def pair_table(nv, nbar, K, n, STR, mass):
    """PP: every vehicle pair with K_eff = (K^(-1/n) + K^(-1/n))^(-n) (two equal Hertz springs in series,
    §13) and every vehicle-barrier pair with K (one vehicle against a rigid barrier), each with the structure
    rows STR[v] (nv, N_STR; crush_structure.structure_row) of its vehicles, zeros for a barrier (rigid), and the
    pair's reduced mass from the vehicles' masses mass[v] (a barrier's pair: the vehicle's)."""
    STR = np.asarray(STR, dtype=float).reshape(nv, N_STR)
    rigid = np.zeros(N_STR)
    pairs = [(i, j, (K ** (-1 / n) + K ** (-1 / n)) ** (-n), *STR[i], *STR[j], mass[i] * mass[j] / (mass[i] + mass[j]))
             for i in range(nv) for j in range(i + 1, nv)]
    pairs += [(i, nv + k, K, *STR[i], *rigid, mass[i]) for i in range(nv) for k in range(nbar)]
    return np.array(pairs, dtype=float).reshape(-1, N_PP)


def barrier_rows(barriers):
    """BAR (nbar, 5): x, y, heading, half length, half width of the scene's barriers."""
    return np.array([[b.x, b.y, b.heading, b.length / 2, b.width / 2] for b in barriers]).reshape(-1, 5)


def contact_arrays(CSH, PP, BAR, nv):
    """The contact tuple handed to `contacts`: CSH, BOXR, BOXA, BOXE, PP, PST, PSG, FX, BPC, OUT, FM (fresh pair
    state, outputs for the 7 stages of a Dormand-Prince step, broad-phase counters, the plan outlines of the
    vehicles and then the barriers, the vehicles' face memories, §13a "Face memory")."""
    nbar = BAR.shape[0]
    BOXR = np.zeros((nbar, 3))
    BOXA = np.zeros((nbar, 3, 3))
    BOXE = np.zeros((nbar, 3))
    for k in range(nbar):
        BOXR[k] = [BAR[k, 0], BAR[k, 1], BARRIER_HALF_HEIGHT]
        BOXA[k] = rot_z(BAR[k, 2])
        BOXE[k] = [BAR[k, 3], BAR[k, 4], BARRIER_HALF_HEIGHT]
    npair = PP.shape[0]
    OUT = np.array([plan_outline(sh) for sh in np.asarray(CSH, dtype=float)]
                   + [box_outline(e[0], e[1]) for e in BOXE]).reshape(-1, N_OUT, 2)
    return (np.ascontiguousarray(CSH, dtype=float), BOXR, BOXA, BOXE, np.ascontiguousarray(PP, dtype=float),
            np.zeros((npair, N_PST)), np.zeros((7, npair, N_PSG)), np.zeros((nv, 7)), np.zeros(N_BPC, np.int64),
            OUT, np.zeros((nv, N_FM)))


def plan_outline(sh):
    """N_OUT vertices of a chassis superellipsoid's plan outline (its z = 0 section) about its centre, counter-
    clockwise at the outward normal angles 2 pi k / N_OUT (its support points: support_local)."""
    phi = 2.0 * np.pi * np.arange(N_OUT) / N_OUT
    return np.array([support_local(math.cos(f), math.sin(f), 0.0, sh[:5])[:2] for f in phi])


def box_outline(a, b):
    """A barrier's plan outline: its four corners counter-clockwise (rows 4.. unused, the last repeated)."""
    return np.array([(a, b), (-a, b), (-a, -b)] + [(a, -b)] * (N_OUT - 3), dtype=float)

