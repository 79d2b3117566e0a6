"""The crush-structure contact law of multibody and exudyn (docs/physics.md §13a): the CRASH3 line as a force per
unit width over the crush from first touch, two structures in series, unloading to the restitution. References
are written here independently: the barrier crush and its time from the energy balance and the linear spring
solved by hand, CRASH3's energy with its G term, a 1-DOF impact integrated with scipy, series springs from force
equilibrium."""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from crashlab.models.common import crush_structure as CS

A, B = 45e3, 450e3           # N/m, N/m^2
B2 = 800e3


def test_barrier_crush_energy_and_time():
    """Against a rigid barrier, a mass m at v with engaged width w crushes to C where 1/2 m v^2 = w B C^2 / 2
    (a linear spring of stiffness w B), at t = pi/2 sqrt(m / (w B)); C is CRASH3's residual crush C_r plus A/B,
    with the energy w (A C_r + B C_r^2/2 + G), G = A^2/2B (Campbell 1974; Strother et al. 1986)."""
    m, v, w = 1719.0, 57.09 / 3.6, 1.837
    c_ref = v * math.sqrt(m / (w * B))
    t_ref = 0.5 * math.pi * math.sqrt(m / (w * B))

    def rhs(t, y, cm):
        c, cd = y
        return [cd, -w * CS.structure_force(c, max(cm[0], c), 0.2, B, 0.0) / m]

    def peak(t, y, cm):
        return y[1]
    peak.terminal = True
    sol = solve_ivp(rhs, (0, 1), [1e-12, v], args=([0.0],), events=peak, rtol=1e-10, atol=1e-12, max_step=1e-3)
    assert sol.y[0, -1] == pytest.approx(c_ref, rel=1e-6)
    assert sol.t[-1] == pytest.approx(t_ref, rel=1e-5)
    cr = c_ref - A / B
    crash3 = w * (A * cr + B * cr * cr / 2 + A * A / (2 * B))
    assert CS.series_energy(c_ref, B, 0.0) * w == pytest.approx(crash3, rel=1e-12)
    assert crash3 == pytest.approx(0.5 * m * v * v, rel=1e-12)


@pytest.mark.parametrize("e", [0.05, 0.1, 0.165, 0.3, 0.6, 0.9])
@pytest.mark.parametrize("other", [0.0, B2])
def test_unloading_gives_the_restitution(e, other):
    """A 1-DOF impact (reduced mass on the law) rebounds with e v: e^2 = E_rebound / E_absorbed."""
    m, v, w = 900.0, 15.0, 1.6
    cm = [0.0]

    def rhs(t, y):
        c, cd = y
        return [cd, -w * CS.structure_force(c, max(cm[0], c), e, B, other) / m]

    # loading up to the turning point, then unloading from that largest crush
    def turn(t, y):
        return y[1]
    turn.terminal, turn.direction = True, -1
    s1 = solve_ivp(rhs, (0, 1), [1e-12, v], events=turn, rtol=1e-11, atol=1e-13, max_step=1e-3)
    cm[0] = s1.y[0, -1]
    cp = CS.permanent_crush(cm[0], e)
    def free(t, y):
        return y[0] - cp - 1e-12
    free.terminal, free.direction = True, -1
    s2 = solve_ivp(rhs, (0, 1), [cm[0], 0.0], events=free, rtol=1e-11, atol=1e-13, max_step=1e-4)
    assert -s2.y[1, -1] / v == pytest.approx(e, rel=1e-4)
    # the unloading line: f_m - k (Cm - Cp) = 0 with the energy f_m^2 / (2k) = e^2 e_m
    fm = CS.series_force(cm[0], B, other)
    em = CS.series_energy(cm[0], B, other)
    assert 0.5 * fm * (cm[0] - cp) == pytest.approx(e * e * em, rel=1e-12)
    assert 0.0 < cp < cm[0]


def test_series_springs_force_equilibrium():
    """Two structures in series carry the same force per unit width; their crushes add up to the total."""
    for c in (0.005, 0.02, 0.1, 0.4, 0.9):
        f = CS.series_force(c, B, B2)
        c1, c2 = CS.crush_share(f, B), CS.crush_share(f, B2)
        assert c1 + c2 == pytest.approx(c, rel=1e-12)
        assert B * c1 == pytest.approx(f, rel=1e-12) and B2 * c2 == pytest.approx(f, rel=1e-12)
    # symmetric in the two structures; equal ones: half the stiffness, each takes half the crush
    assert CS.series_force(0.3, B2, B) == pytest.approx(CS.series_force(0.3, B, B2), rel=1e-12)
    assert CS.series_force(0.3, B, B) == pytest.approx(B / 2 * 0.3, rel=1e-12)
    # the energy is the integral of the force
    c = np.linspace(0.0, 0.9, 20001)
    f = np.array([CS.series_force(x, B, B2) for x in c])
    assert CS.series_energy(0.9, B, B2) == pytest.approx(np.trapezoid(f, c), rel=1e-6)


def test_rigid_barrier_is_the_stiff_limit():
    """A barrier (B <= 0) is the limit of an infinitely stiff second structure."""
    for c in (0.01, 0.3, 0.8):
        assert CS.series_force(c, B, 1e15) == pytest.approx(CS.series_force(c, B, 0.0), rel=1e-6)


def test_reloading_follows_the_unloading_line():
    cm, e = 0.5, 0.2
    cp = CS.permanent_crush(cm, e)
    assert cp == pytest.approx(cm * (1 - e * e), rel=1e-12)
    assert CS.structure_force(cp - 1e-6, cm, e, B, 0.0) == 0.0
    mid = 0.5 * (cp + cm)
    assert CS.structure_force(mid, cm, e, B, 0.0) == pytest.approx(0.5 * B * cm, rel=1e-9)
    assert CS.structure_force(cm + 0.1, cm, e, B, 0.0) == pytest.approx(B * (cm + 0.1), rel=1e-12)


def test_structure_row_reads_the_vehicles_structure_and_names_class_defaults():
    from crashlab.structure import Structure, class_structure
    defaults = class_structure("mid-size")

    class Spec:
        width, length = 1.8, 4.6
        structure = {"front": Structure(70e3, 900e3, 1.4, "test"),
                     "rear": Structure(*defaults["rear"][:2], 1.8, defaults["rear"][2], default=True),
                     "side": Structure(*defaults["side"][:2], 4.6, defaults["side"][2], default=True)}
    row, notes = CS.structure_row(Spec())
    assert list(row[:3]) == [70e3, 900e3, 1.4]
    assert list(row[3:6]) == [*defaults["rear"][:2], 1.8]
    assert list(row[6:9]) == [*defaults["side"][:2], 4.6]
    assert len(notes) == 2 and all("class default" in n for n in notes)


def test_side_code():
    assert CS.side_code(2.0, 0.1, 2.3, 0.9) == 0
    assert CS.side_code(-2.0, 0.1, 2.3, 0.9) == 1
    assert CS.side_code(0.5, 0.9, 2.3, 0.9) == 2
