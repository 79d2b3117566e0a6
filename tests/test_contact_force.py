"""Normal force laws, the restitution they produce, friction laws, and the bouncing ball with and
without contact-onset control (docs/physics.md §13, §14, §15)."""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from crashlab.models.common.contact_force import (
    FRICTION_LAWS,
    FRICTION_V0,
    FRICTION_V1,
    FRICTION_VS,
    LAWS,
    chi,
    exact_chi,
    friction_code,
    friction_ratio_code,
    normal_force_chi,
    normal_law_name,
    restitution_relation,
)


# ----------------------------------------------------------------------------------------------------
# convenience forms of the laws, used only here
# ----------------------------------------------------------------------------------------------------
def restitution_from_chi(c):
    """e* produced by F_N = K delta^n (1 + c delta_dot/delta_dot0), F_N >= 0 (§13)."""
    if c <= 0.0:
        return 1.0
    return brentq(lambda es: restitution_relation(c, es), 0.0, 1.0 / c, xtol=1e-14, rtol=1e-14, maxiter=200)


def effective_restitution(law, e):
    """Restitution the law actually produces for the target e (§13)."""
    return restitution_from_chi(chi(law, e))


def hertz_stiffness(E1, nu1, R1, E2=None, nu2=None, R2=None):
    """K = 4/3 E* sqrt(R*) (§13). E2=None: rigid body 2; R2=None: plane (R* = R1)."""
    inv_E = (1 - nu1 ** 2) / E1 + (0.0 if E2 is None else (1 - nu2 ** 2) / E2)
    Rs = R1 if R2 is None else R1 * R2 / (R1 + R2)
    return 4.0 / 3.0 / inv_E * math.sqrt(Rs)


def normal_force(law, delta, delta_dot, delta_dot0, K, e=1.0, n=1.5, v_min=1e-3):
    """Normal force of a named law (see module docstring); F_N >= 0. Hertz uses n = 1.5 by definition
    of the law, the others take n (1.5 for Hertzian contact, 1 for a linear stiffness)."""
    law = normal_law_name(law)
    return normal_force_chi(float(delta), float(delta_dot), float(delta_dot0), float(K), chi(law, e),
                            1.5 if law == "hertz" else float(n), float(v_min))


def friction_ratio(law, v, v0=FRICTION_V0, v1=FRICTION_V1, v_s=FRICTION_VS):
    """Vectorised c(|v_T|) in [0, 1] of a friction law (F_T magnitude / (mu F_N))."""
    code = friction_code(law)
    if law == "threlfall" and v0 <= 0:
        raise ValueError("threlfall needs v0 > 0")
    if law == "ambrosio" and not v1 > v0 >= 0:
        raise ValueError("ambrosio needs v1 > v0 >= 0")
    v = np.asarray(v, float)
    out = np.vectorize(lambda x: friction_ratio_code(code, x, v0, v1, v_s), otypes=[float])(v)
    return out if out.ndim else float(out)


def friction_force(law, v_rel, normal, F_N, mu, v0=FRICTION_V0, v1=FRICTION_V1, v_s=FRICTION_VS):
    """F_T = -mu c(|v_T|) F_N v_T/|v_T| with v_T = v_rel - (v_rel.n) n (§14); zero for v_T = 0."""
    v_rel = np.asarray(v_rel, float)
    n = np.asarray(normal, float)
    vT = v_rel - (v_rel @ n) * n
    s = float(np.linalg.norm(vT))
    if s == 0.0 or F_N <= 0.0:
        return np.zeros(3)
    return -mu * friction_ratio(law, s, v0, v1, v_s) * F_N * vT / s


E_TAB = [0.01, 0.05, 0.10, 0.20, 0.30, 0.50, 0.70, 0.90]
TABLE_41 = {  # docs/physics.md §13
    "hunt-crossley": [0.490, 0.501, 0.516, 0.547, 0.581, 0.663, 0.768, 0.909],
    "lankarani-nikravesh": [0.663, 0.664, 0.665, 0.672, 0.684, 0.725, 0.796, 0.913],
    "flores": [0.006, 0.033, 0.069, 0.156, 0.256, 0.470, 0.683, 0.894],
    "gonthier": [0.010, 0.050, 0.101, 0.205, 0.304, 0.488, 0.670, 0.876],
}
EXACT_CHI_TAB = [100.0, 20.0, 10.0, 4.92, 3.09, 1.43, 0.635, 0.166]


@pytest.mark.parametrize("law", list(TABLE_41))
def test_effective_restitution_matches_table(law):
    got = [effective_restitution(law, e) for e in E_TAB]
    assert np.allclose(got, TABLE_41[law], atol=0.0015)


def test_exact_chi():
    for e, c in zip(E_TAB, EXACT_CHI_TAB):
        assert abs(exact_chi(e) - c) < 0.006 * c
        assert abs(effective_restitution("exact-restitution", e) - e) < 1e-10
    assert effective_restitution("hertz", 0.3) == 1.0
    assert chi("flores", 0.5) == pytest.approx(1.6) and chi("gonthier", 0.5) == pytest.approx(1.5)
    assert chi("hunt-crossley", 0.5) == pytest.approx(0.75)
    assert chi("lankarani-nikravesh", 0.5) == pytest.approx(0.5625)
    n = exact_chi.cache_info().hits
    exact_chi(0.5)
    assert exact_chi.cache_info().hits == n + 1  # cached
    with pytest.raises(ValueError):
        chi("nope", 0.5)


def test_normal_force_clamp_and_form():
    K = 1e9
    for law in LAWS:
        assert normal_force(law, -1e-3, 1.0, 1.0, K, 0.3) == 0.0
        assert normal_force(law, 0.0, 1.0, 1.0, K, 0.3) == 0.0
        # fast separation: the damping term would pull; the force is clamped at 0
        assert normal_force(law, 1e-3, -100.0, 1.0, K, 0.3) >= 0.0
        f = normal_force(law, 1e-3, 0.5, 1.0, K, 0.3)
        assert f == pytest.approx(K * 1e-3 ** 1.5 * (1 + chi(law, 0.3) * 0.5))
    # grazing onset: delta_dot0 clamped to v_min
    assert normal_force_chi(1e-3, 1e-3, 0.0, K, 2.0, 1.5, 1e-2) == pytest.approx(K * 1e-3 ** 1.5 * 1.2)
    assert hertz_stiffness(2.07e11, 0.3, 0.1) == pytest.approx(4 / 3 * 2.07e11 / 0.91 * math.sqrt(0.1))
    assert hertz_stiffness(2e11, 0.3, 0.1, 2e11, 0.3, 0.1) == pytest.approx(
        4 / 3 / (2 * 0.91 / 2e11) * math.sqrt(0.05))


@pytest.mark.parametrize("law", FRICTION_LAWS)
def test_friction_limits(law):
    v = np.linspace(0, 5, 2001)
    c = friction_ratio(law, v, v0=0.01, v1=0.1, v_s=0.01)
    assert c[0] == 0.0
    assert np.all(np.diff(c) >= -1e-15)  # monotone (non-decreasing)
    assert np.all((c >= 0) & (c <= 1))
    assert c[-1] > 0.99999  # mu F_N at large slip
    mu, FN = 0.4, 1000.0
    F = friction_force(law, [3.0, 0.0, 7.0], [0, 0, 1], FN, mu)
    assert F[2] == 0.0 and F[0] < 0 and abs(np.linalg.norm(F) - mu * FN) < 1e-3 * mu * FN
    assert np.all(friction_force(law, [0, 0, 2.0], [0, 0, 1], FN, mu) == 0)
    if law == "threlfall":
        assert friction_ratio(law, 0.01, v0=0.01) == pytest.approx(1 - math.exp(-3))  # 95 % at v0
    if law == "ambrosio":
        assert friction_ratio(law, 0.005, v0=0.01, v1=0.1) == 0.0  # no static friction below v0
        assert friction_ratio(law, 0.055, v0=0.01, v1=0.1) == pytest.approx(0.5)


# ----------------------------------------------------------------------------------------------------
# bouncing ball: sphere m = 1 kg, R = 0.1 m, bottom dropped from 0.9 m onto a rigid plane, steel-like K
# ----------------------------------------------------------------------------------------------------
G_ACC, M, R, H = 9.81, 1.0, 0.1, 0.9
K_BALL = hertz_stiffness(2.07e11, 0.3, R)  # steel sphere on a rigid plane: 9.6e10 N/m^1.5


def _contact_phase(z0, v0, law, e):
    """Resolve one contact from (z0, v0) (delta_dot0 = -v0) to separation; returns the exit velocity."""
    c = chi(law, e)
    vd0 = -v0

    def f(t, y):
        return [y[1], -G_ACC + normal_force_chi(R - y[0], -y[1], vd0, K_BALL, c, 1.5, 1e-3) / M]

    def sep(t, y):
        return y[0] - R
    sep.terminal, sep.direction = True, 1
    tc = 3.3 * (M / K_BALL) ** 0.4 * vd0 ** -0.2  # Hertz contact duration estimate
    sol = solve_ivp(f, (0, 50 * tc), [z0, v0], method="DOP853", rtol=1e-11, atol=1e-14, events=sep,
                    max_step=tc / 200)
    assert sol.status == 1
    return sol.y_events[0][0][1]


def bounce(law, e, control=True, dt=1e-3):
    """Effective restitution v_out / v_in. control=True: solve_ivp with a terminal event at the gap's
    zero crossing (first-contact control, §8): contact starts at delta = 0. control=False: fixed-step
    (dt) explicit (symplectic Euler) free flight, contact started when penetration is first seen, with
    that penetration and that velocity as delta_dot0 (the contact itself is still resolved accurately,
    so the difference is the onset alone)."""
    if control:
        def hit(t, y):
            return y[0] - R
        hit.terminal, hit.direction = True, -1
        s = solve_ivp(lambda t, y: [y[1], -G_ACC], (0, 2), [R + H, 0.0], rtol=1e-12, atol=1e-14, events=hit)
        z0, v0 = R, s.y_events[0][0][1]
    else:
        z0, v0 = R + H, 0.0
        while z0 >= R:
            v0 -= G_ACC * dt
            z0 += v0 * dt
    return _contact_phase(z0, v0, law, e) / -v0


LAWS_05 = ("flores", "lankarani-nikravesh", "hunt-crossley", "gonthier")


def test_bouncing_ball_with_and_without_onset_control():
    lines = []
    for law in LAWS_05:
        pred = effective_restitution(law, 0.5)
        ec, ef = bounce(law, 0.5), bounce(law, 0.5, control=False)
        lines.append(f"{law:20s} e=0.5 predicted {pred:.4f}  controlled {ec:.4f}  no control {ef:.4f}")
        assert abs(ec - pred) < 0.01
        assert abs(ef - pred) > abs(ec - pred) + 0.05  # the onset error dominates
    for e in (0.1, 0.3, 0.5, 0.9):
        ec, ef = bounce("exact-restitution", e), bounce("exact-restitution", e, control=False)
        lines.append(f"exact-restitution    e={e}  controlled {ec:.4f}  no control {ef:.4f}")
        assert abs(ec - e) < 0.01
        if e >= 0.3:  # at e = 0.1 the large chi dissipates the spurious initial energy (see report)
            assert abs(ef - e) > abs(ec - e) + 0.02
    print("\n" + "\n".join(lines))
