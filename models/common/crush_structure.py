"""Crush structure of the chassis contact (docs/physics.md §13a): the CRASH3 force per unit of engaged width of
the struck side of each vehicle, the two structures in series, and the unloading that gives the impact's
restitution. Used by common/chassis_contact.py (multibody's time loop, exudyn's loads).

Loading, one structure (Campbell 1974; CRASH3): f = F/w = A + B C, C >= 0 its crush.
Two structures in series (force equilibrium: the same f on both): with A1 <= A2, only the weaker one crushes up
to C* = (A2 - A1)/B1; beyond it both do, f = A2 + Bs (C - C*), Bs = B1 B2/(B1 + B2). A rigid barrier is
B2 = A2 = inf (rows with B <= 0 are rigid): f = A1 + B1 C. Crush share of a structure: (f - A)/B (>= 0).
Energy per unit width e(C) = integral of f: A1 C + B1 C^2/2 below C*, e(C*) + A2 (C - C*) + Bs (C - C*)^2/2.
Unloading from the largest crush Cm (f_m = f(Cm), e_m = e(Cm)): linear, slope k = f_m^2 / (2 e^2 e_m), so that
the energy given back f_m^2/(2k) is e^2 e_m (e^2 = E_rebound / E_absorbed, the impact's restitution); reloading
follows the same line up to Cm, then the loading law. The line reaches f = 0 at the permanent crush
Cp = Cm - f_m / k = Cm - 2 e^2 e_m / f_m (>= Cm (1 - 2 e^2) >= 0 for e <= 1/sqrt 2).

The vehicle's coefficients come from crashlab.structure: its file's [structure.front|rear|side] A, B, width, else
the class default there (the one home of those numbers, docs/physics.md §28).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from crashlab.structure import STRUCTURE_SIDES as SIDES

# per-vehicle structure row: A [N/m], B [N/m^2], width [m] of front, rear, side
N_STR = 9
# restitution range of the linear unloading (Cp >= 0 needs e <= 1/sqrt 2)
E_LO, E_HI = 0.01, 0.7


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
    """e within [E_LO, E_HI] and a reason when it had to move (the caller warns)."""
    if e < E_LO:
        return E_LO, f"restitution {e:g} below {E_LO:g}: the crush unloading uses {E_LO:g}"
    if e > E_HI:
        return E_HI, (f"restitution {e:g} above {E_HI:g}: the linear crush unloading would end with a negative "
                      f"permanent crush; it uses {E_HI:g} (docs/physics.md §13a)")
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
    """Struck side of a point (x, y) in the chassis frame relative to the shape centre, a and b the half length
    and half width: 0 front, 1 rear, 2 side (the bounding box face it is nearest in proportion)."""
    if abs(x) * b >= abs(y) * a:
        return 0 if x >= 0.0 else 1
    return 2


@njit(cache=True)
def face_normal_angle(x, y, a, b):
    """Outward normal angle, in the body frame, of the bounding-box face nearest in proportion to the point (x, y)
    (side_code's rule): 0 front (+x), pi rear, pi/2 left side (+y), -pi/2 right side."""
    if abs(x) * b >= abs(y) * a:
        return 0.0 if x >= 0.0 else math.pi
    return 0.5 * math.pi if y >= 0.0 else -0.5 * math.pi


@njit(cache=True)
def engagement_normal(fi, fj, A1, A2, barrier):
    """The plan contact normal (from i towards j) of an engaged crush (docs/physics.md §13a): the bisector of the
    struck faces' outward normals n_i and -n_j, each turned with its body (face angles fi, fj in the body frames,
    rotations A1, A2); against a barrier (rigid: it does not crush) its face's normal alone. Returns (e0, e1, ok);
    ok False where two vehicles' faces do not face each other (n_i . n_j >= 0)."""
    c, s = math.cos(fj), math.sin(fj)
    nj0, nj1 = A2[0, 0] * c + A2[0, 1] * s, A2[1, 0] * c + A2[1, 1] * s
    if barrier:
        e0, e1 = -nj0, -nj1
    else:
        c, s = math.cos(fi), math.sin(fi)
        ni0, ni1 = A1[0, 0] * c + A1[0, 1] * s, A1[1, 0] * c + A1[1, 1] * s
        if ni0 * nj0 + ni1 * nj1 >= 0.0:
            return 0.0, 0.0, False
        e0, e1 = ni0 - nj0, ni1 - nj1
    n = math.sqrt(e0 * e0 + e1 * e1)
    if n < 1e-9:
        return 0.0, 0.0, False
    return e0 / n, e1 / n, True


@njit(cache=True)
def series_force(C, A1, B1, A2, B2):
    """Force per unit width f(C) of two structures in series at total crush C >= 0 (B2 <= 0: rigid)."""
    if C <= 0.0:
        return 0.0
    if B2 <= 0.0:
        return A1 + B1 * C
    if A2 < A1:
        A1, B1, A2, B2 = A2, B2, A1, B1
    cs = (A2 - A1) / B1
    if C <= cs:
        return A1 + B1 * C
    return A2 + B1 * B2 / (B1 + B2) * (C - cs)


@njit(cache=True)
def series_energy(C, A1, B1, A2, B2):
    """Energy per unit width e(C) = integral of series_force from 0 to C."""
    if C <= 0.0:
        return 0.0
    if B2 <= 0.0:
        return A1 * C + 0.5 * B1 * C * C
    if A2 < A1:
        A1, B1, A2, B2 = A2, B2, A1, B1
    cs = (A2 - A1) / B1
    if C <= cs:
        return A1 * C + 0.5 * B1 * C * C
    d = C - cs
    return A1 * cs + 0.5 * B1 * cs * cs + A2 * d + 0.5 * B1 * B2 / (B1 + B2) * d * d


@njit(cache=True)
def crush_share(f, A, B):
    """Crush of one structure (A, B) carrying the force per unit width f (0 for a rigid one, B <= 0)."""
    if B <= 0.0 or f <= A:
        return 0.0
    return (f - A) / B


@njit(cache=True)
def permanent_crush(Cm, e, A1, B1, A2, B2):
    """Cp: where the unloading line from the largest crush Cm reaches f = 0 (0 before any crush)."""
    if Cm <= 0.0:
        return 0.0
    fm = series_force(Cm, A1, B1, A2, B2)
    return Cm - 2.0 * e * e * series_energy(Cm, A1, B1, A2, B2) / fm


@njit(cache=True)
def structure_force(C, Cm, e, A1, B1, A2, B2):
    """Force per unit width at total crush C with the largest crush so far Cm: the loading law at C >= Cm, else
    the unloading line of slope f_m^2 / (2 e^2 e_m) through (Cm, f_m), clamped at 0."""
    if C <= 0.0:
        return 0.0
    if C >= Cm:
        return series_force(C, A1, B1, A2, B2)
    fm = series_force(Cm, A1, B1, A2, B2)
    k = fm * fm / (2.0 * e * e * series_energy(Cm, A1, B1, A2, B2))
    f = fm - k * (Cm - C)
    return f if f > 0.0 else 0.0
