"""Crush structure of the chassis contact (docs/physics.md §13a): the CRASH3 structure of the struck side of each
vehicle as a force per unit of engaged width, the two structures in series, and the unloading that gives the impact's
restitution. Used by common/chassis_contact.py (multibody's time loop, exudyn's loads).

Loading, one structure: the CRASH3 line F/w = A + B C_r over the residual crush C_r, with its energy term G = A^2/2B,
is the line f = B C over the crush C counted from the first touch, C = C_r + A/B (Campbell 1974: A/B = b0/b1, the
deformation of the no-damage speed b0, which springs back; the energy to C is B C^2/2 = A C_r + B C_r^2/2 + G).
Two structures in series (force equilibrium: the same f on both, each crushing f/B_k): f = Bs C,
Bs = B1 B2/(B1 + B2); a rigid barrier is B2 = inf (rows with B <= 0 are rigid): f = B1 C. Energy per unit width
e(C) = Bs C^2/2.
Unloading from the largest crush Cm (f_m = f(Cm), e_m = e(Cm)): linear, slope k = f_m^2 / (2 e^2 e_m) = Bs/e^2, so
that the energy given back f_m^2/(2k) is e^2 e_m (e^2 = E_rebound / E_absorbed, the impact's restitution);
reloading follows the same line up to Cm, then the loading law. The line reaches f = 0 at the permanent crush
Cp = Cm (1 - e^2).

The vehicle's coefficients come from crashlab.structure: its file's [structure.front|rear|side] A, B, width, else
the class default there (the one home of those numbers, docs/physics.md §28); A is the CRASH3 residual-crush
intercept and does not enter the force.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from crashlab.structure import STRUCTURE_SIDES as SIDES

# per-vehicle structure row: A [N/m], B [N/m^2], width [m] of front, rear, side
N_STR = 9
# restitution range of the linear unloading
E_LO, E_HI = 0.01, 1.0
# damping ratio of the crushed structures in a push (docs/physics.md §13a "Push damping"): critical, a crushed
# structure pressed again does not ring
PUSH_DAMPING_RATIO = 1.0


def structure_row(spec):
    """The vehicle's structure row [A, B, width] x (front, rear, side) from its crashlab.structure (the file's
    [structure.<side>] or the class default of crashlab.structure) and notes naming what is a class default."""
    row, notes = np.zeros(N_STR), []
    for k, side in enumerate(SIDES):
        entry = spec.structure[side]
        row[3 * k:3 * k + 3] = (entry.A, entry.B, entry.width)
        if entry.default:
            notes.append(f"structure.{side}: A = {entry.A:g} N/m, B = {entry.B:g} N/m^2 ({entry.source})")
    return row, notes


def clamp_restitution(e):
    """e at least E_LO (the unloading slope Bs/e^2 stays finite) and a reason when it had to move (the caller
    warns); the scene's schema holds e <= E_HI."""
    if e < E_LO:
        return E_LO, f"restitution {e:g} below {E_LO:g}: the crush unloading uses {E_LO:g}"
    return e, None


def speed_law_setting(impact, contact_law, why):
    """The warning of a scene's restitution for the 3D chassis contact: restitution = "speed" needs the structure
    law (its unloading takes e per pair from the closing speed, §13b; the generic law's damping is set once from
    the constant); a constant keeps clamp_restitution's reason `why` (structure law only)."""
    if impact.restitution_law != "speed":
        return why if contact_law == "structure" else None
    if contact_law == "structure":
        return None
    return (f'restitution = "speed" needs contact_law = "structure": the generic contact law uses the constant '
            f"restitution {impact.restitution:g} (docs/physics.md §13b)")


@njit(cache=True)
def side_code(x, y, a, b):
    """Struck face of a point (x, y) in the chassis frame relative to the shape centre, a and b the half length
    and half width: 0 front, 1 rear, 2 left (y >= 0), 3 right (crashlab.structure.STRUCK_FACES: the bounding box
    face it is nearest in proportion)."""
    if abs(x) * b >= abs(y) * a:
        return 0 if x >= 0.0 else 1
    return 2 if y >= 0.0 else 3


@njit(cache=True)
def face_code(x, y, z, a, b, c):
    """Struck face of a point (x, y, z) in the chassis frame relative to the shape centre, a, b, c the half length,
    width and height: side_code's four faces, or 4 the roof (z >= 0), 5 the underbody where the point is nearer to
    those in proportion (crashlab.structure.IMPACT_FACES; a tilted body, docs/physics.md §13a "A tilted body");
    c <= 0: the plan's four faces only (a barrier)."""
    if c > 0.0 and abs(z) * a >= abs(x) * c and abs(z) * b >= abs(y) * c:
        return 4 if z >= 0.0 else 5
    return side_code(x, y, a, b)


@njit(cache=True)
def swept_faces(dx, dy, wx, wy, c1, s1, a1, b1, c2, s2, a2, b2):
    """The struck faces of two upright bodies at their first touch, from their approach (docs/physics.md §13a
    "Struck faces"): their plan bounding boxes (half length a, half width b, heading axis (c, s); centre j less
    centre i (dx, dy)) moved back along the velocity of j relative to i at the touch (wx, wy). Along each box
    axis the projections began to overlap a time tau ago (the overlap left over the closing speed along it, the
    separating-axis test in time); each body's struck face is the one of its own two axes whose overlap began the
    later, on the side facing the other. Returns (fi, fj, ok) (side_code's codes); ok False where a body's
    axes do not close (no approach)."""
    fi, fj, tau_i, tau_j = -1, -1, np.inf, np.inf
    for k in range(4):
        if k == 0:
            ux, uy = c1, s1
        elif k == 1:
            ux, uy = -s1, c1
        elif k == 2:
            ux, uy = c2, s2
        else:
            ux, uy = -s2, c2
        reach = (a1 * abs(ux * c1 + uy * s1) + b1 * abs(-ux * s1 + uy * c1)
                 + a2 * abs(ux * c2 + uy * s2) + b2 * abs(-ux * s2 + uy * c2))
        s0 = ux * dx + uy * dy
        sgn = 1.0 if s0 >= 0.0 else -1.0
        closing = -sgn * (ux * wx + uy * wy)
        if closing <= 1e-9:
            continue
        tau = max(reach - abs(s0), 0.0) / closing
        # the face towards the other body: i's along +sgn u, j's along -sgn u (u its x axis for k = 0, 2, else y)
        along, across = (sgn, 0.0) if k % 2 == 0 else (0.0, sgn)
        if k < 2 and tau < tau_i:
            tau_i, fi = tau, side_code(along, across, a1, b1)
        elif k >= 2 and tau < tau_j:
            tau_j, fj = tau, side_code(-along, -across, a2, b2)
    return fi, fj, fi >= 0 and fj >= 0


@njit(cache=True)
def structure_slot(code):
    """The structure of a struck face (face_code): 0 front, 1 rear, 2 side for either flank, and for the roof and
    the underbody, which have no CRASH3 structure (docs/physics.md §13a "A tilted body"; the rows of structure_row,
    crashlab.structure.FACE_STRUCTURE)."""
    return code if code < 2 else 2


@njit(cache=True)
def face_normal(code):
    """Outward unit normal, in the body frame, of a struck face (face_code): front +x, rear -x, left +y, right -y,
    roof +z, underbody -z."""
    if code == 0:
        return 1.0, 0.0, 0.0
    if code == 1:
        return -1.0, 0.0, 0.0
    if code == 2:
        return 0.0, 1.0, 0.0
    if code == 3:
        return 0.0, -1.0, 0.0
    if code == 4:
        return 0.0, 0.0, 1.0
    return 0.0, 0.0, -1.0


@njit(cache=True)
def engagement_normal(fi, fj, A1, A2, barrier):
    """The plan contact normal (from i towards j) of an engaged crush (docs/physics.md §13a): the bisector of the
    plan components of the struck faces' outward normals n_i and -n_j, each turned with its body (face codes fi,
    fj, face_code; rotations A1, A2); against a barrier (rigid: it does not crush) its face's normal alone. Returns
    (e0, e1, ok); ok False where two vehicles' faces do not face each other (n_i . n_j >= 0) or the normals have
    no plan direction."""
    x, y, z = face_normal(int(fj))
    nj0 = A2[0, 0] * x + A2[0, 1] * y + A2[0, 2] * z
    nj1 = A2[1, 0] * x + A2[1, 1] * y + A2[1, 2] * z
    if barrier:
        e0, e1 = -nj0, -nj1
    else:
        x, y, z = face_normal(int(fi))
        ni0 = A1[0, 0] * x + A1[0, 1] * y + A1[0, 2] * z
        ni1 = A1[1, 0] * x + A1[1, 1] * y + A1[1, 2] * z
        if ni0 * nj0 + ni1 * nj1 >= 0.0:
            return 0.0, 0.0, False
        e0, e1 = ni0 - nj0, ni1 - nj1
    n = math.sqrt(e0 * e0 + e1 * e1)
    if n < 1e-9:
        return 0.0, 0.0, False
    return e0 / n, e1 / n, True


@njit(cache=True)
def series_stiffness(B1, B2):
    """Stiffness per unit width of two structures in series, B1 B2 / (B1 + B2); a rigid partner (B2 <= 0): B1."""
    if B2 <= 0.0:
        return B1
    return B1 * B2 / (B1 + B2)


@njit(cache=True)
def series_force(C, B1, B2):
    """Force per unit width f(C) = Bs C of two structures in series at total crush C >= 0 (B2 <= 0: rigid)."""
    if C <= 0.0:
        return 0.0
    return series_stiffness(B1, B2) * C


@njit(cache=True)
def series_energy(C, B1, B2):
    """Energy per unit width e(C) = Bs C^2 / 2, the integral of series_force from 0 to C."""
    if C <= 0.0:
        return 0.0
    return 0.5 * series_stiffness(B1, B2) * C * C


@njit(cache=True)
def crush_share(f, B):
    """Crush of one structure (stiffness B) carrying the force per unit width f (0 for a rigid one, B <= 0)."""
    if B <= 0.0 or f <= 0.0:
        return 0.0
    return f / B


@njit(cache=True)
def permanent_crush(Cm, e):
    """Cp: where the unloading line from the largest crush Cm reaches f = 0: Cm - 2 e^2 e_m / f_m = Cm (1 - e^2)
    for the linear loading (0 before any crush)."""
    if Cm <= 0.0:
        return 0.0
    return Cm * (1.0 - e * e)


@njit(cache=True)
def push_damping(dd, e, B1, B2, width, m_eff):
    """Kelvin-Voigt force of the crushed structures in a push (docs/physics.md §13a "Push damping"), c dd at the
    normal closing speed dd: c = 2 zeta sqrt(k m_eff), zeta = PUSH_DAMPING_RATIO, k = width Bs / e^2 the stiffness
    of the unloading line over the engaged width, m_eff the pair's reduced mass (chassis_contact.pair_table)."""
    k = width * series_stiffness(B1, B2) / (e * e)
    return 2.0 * PUSH_DAMPING_RATIO * math.sqrt(k * m_eff) * dd


@njit(cache=True)
def strip_force(C, m1, m2, e, B1, B2):
    """Force per unit width of two structures in series at total crush C, each with its own largest crush so far
    m1, m2 (docs/physics.md §13a "Face memory"): structure q crushes c_q(f) = f / B_q on its loading line (f >= B_q
    m_q), else m_q (1 - e^2) + f e^2 / B_q on its unloading line (slope B_q / e^2 through (m_q, B_q m_q)); the
    force f solves c_1(f) + c_2(f) = C (piecewise linear, increasing), 0 below the permanent sets. A rigid partner
    (B2 <= 0) does not crush. Returns (f, c_1, c_2); with m_q = m B_s / B_q (one pair's memory m, shared as its
    loading shares it) f is structure_force(C, m, ...). Below the permanent sets c_1 = c_2 = 0."""
    e2 = e * e
    rigid = B2 <= 0.0
    m1 = max(m1, 0.0)
    m2 = 0.0 if rigid else max(m2, 0.0)
    F1 = B1 * m1
    F2 = 0.0 if rigid else B2 * m2
    f = series_force(C, B1, B2)
    if f >= F1 and f >= F2:  # both on their loading lines (new crush: the usual case), as series_force
        return f, f / B1, 0.0 if rigid else f / B2
    F2 = math.inf if rigid else F2
    c_lo = (m1 + m2) * (1.0 - e2)
    if C <= c_lo:
        return 0.0, 0.0, 0.0
    f_lo, f = 0.0, 0.0
    for q in range(3):  # the breakpoints F1, F2 in order, then no bound
        up = min(F1, F2) if q == 0 else (max(F1, F2) if q == 1 else math.inf)
        if up <= f_lo:
            continue
        slope = (e2 if f_lo < F1 else 1.0) / B1 + (0.0 if rigid else (e2 if f_lo < F2 else 1.0) / B2)
        if up == math.inf or C <= c_lo + slope * (up - f_lo):
            f = f_lo + (C - c_lo) / slope
            break
        c_lo += slope * (up - f_lo)
        f_lo = up
    c1 = m1 * (1.0 - e2) + f * e2 / B1 if f < F1 else f / B1
    c2 = 0.0 if rigid else (m2 * (1.0 - e2) + f * e2 / B2 if f < F2 else f / B2)
    return f, c1, c2


@njit(cache=True)
def structure_force(C, Cm, e, B1, B2):
    """Force per unit width at total crush C with the pair's largest crush so far Cm: the loading law at C >= Cm,
    else the unloading line of slope f_m^2 / (2 e^2 e_m) = Bs / e^2 through (Cm, f_m), clamped at 0: strip_force
    with Cm shared as one loading shares it (each structure Cm Bs / B_q; one home for the law)."""
    bs = series_stiffness(B1, B2)
    return strip_force(C, Cm * bs / B1, Cm * bs / B2 if B2 > 0.0 else 0.0, e, B1, B2)[0]
