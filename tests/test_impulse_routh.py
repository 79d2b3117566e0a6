"""Routh's impulse law (docs/physics.md §3) against a reference written here: the impulse-space equations
integrated numerically with scipy's solve_ivp, events at zero slip and at the end of compression, restitution
ended by Stronge's energetic coefficient.

The reference shares no code with models/impulse/laws.py: it builds the point's compliance K from the
post-impact formulas (v1' = v1 - Π/m1, ω1' = ω1 - (r1 × Π)/I1, the mirror for body 2) by applying unit
impulses, integrates, in the normal impulse p,
    dPt/dp = -sg mu while the point slips with sign sg,   = -K_nt/K_tt while it sticks,
    dg/dp = K (1, dPt/dp),   dW/dp = g_n   (W: the work of the normal impulse),
stops the slip phase at the event g_t = 0 (then sticks if |K_nt| <= mu K_tt, else slips the other way),
ends compression at the event g_n = 0 and restitution at the event W = (1 - e^2) W_c.

Seeded random impacts (N_IMPACTS): masses 700-3000 kg, yaw inertias m k^2 with k 0.9-1.6 m, points of
impact anywhere on car-sized outlines, any normal, velocities up to 30 m/s and yaw rates up to 3 rad/s,
contact friction 0-1.2, restitution 0-0.6 (0 in a quarter), a rigid barrier (inverse mass and inertia 0)
in a quarter, and in a tenth no initial slip (|g_t| within the no-slip tolerance SLIP_TOL |g_n|).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from crashlab.models.impulse.laws import (
    BRACH,
    KUDLICH_SLIBAR,
    REVERSED,
    ROUTH,
    SLIDING,
    SLIP_OVERSHOOT,
    SLIP_REVERSES,
    SLIP_TOL,
    checked_impulse,
    collision_impulse,
    impact_matrix,
)

N_IMPACTS = 2000
SEED = 23
REF_REL = 1e-6  # Routh against the reference: delta-V and yaw-rate change, relative
EQUAL_REL = 1e-9  # Routh against the other laws where they must agree
ENERGY_REL = 1e-9  # no impact creates energy: T' <= T (1 + ENERGY_REL)


def cross(a, b):
    return a[0] * b[1] - a[1] * b[0]


class Bodies:
    """Two bodies at an impact point (body 2 rigid ground when w2 = iI2 = 0): the post-impact formulas."""

    def __init__(self, m1, i1, m2, i2, r1, r2, n, v1, om1, v2, om2):
        self.m = (m1, m2)
        self.i = (i1, i2)
        self.w = (1.0 / m1, 0.0 if m2 == math.inf else 1.0 / m2)
        self.ii = (1.0 / i1, 0.0 if i2 == math.inf else 1.0 / i2)
        self.r = (np.asarray(r1, float), np.asarray(r2, float))
        self.v = (np.asarray(v1, float), np.asarray(v2, float))
        self.om = (om1, om2)
        self.n = np.asarray(n, float)
        self.t = np.array([-n[1], n[0]])

    def after(self, impulse):
        """(v1', ω1', v2', ω2') for the impulse (global) on body 2, its opposite on body 1."""
        p = np.asarray(impulse, float)
        v1 = self.v[0] - p * self.w[0]
        o1 = self.om[0] - cross(self.r[0], p) * self.ii[0]
        v2 = self.v[1] + p * self.w[1]
        o2 = self.om[1] + cross(self.r[1], p) * self.ii[1]
        return v1, o1, v2, o2

    def g(self, v1, o1, v2, o2):
        """Velocity of body 2 relative to body 1 at the point (global)."""
        r1, r2 = self.r
        return (v2 + o2 * np.array([-r2[1], r2[0]])) - (v1 + o1 * np.array([-r1[1], r1[0]]))

    def g0(self):
        return self.g(self.v[0], self.om[0], self.v[1], self.om[1])

    def nt(self, g):
        return float(g @ self.n), float(g @ self.t)

    def compliance(self):
        """K (n-t frame): the change of g per unit impulse along n and along t, by applying them."""
        base = self.g0()
        cols = [self.nt(self.g(*self.after(d)) - base) for d in (self.n, self.t)]
        return np.array([[cols[0][0], cols[1][0]], [cols[0][1], cols[1][1]]])

    def energy(self, v1, o1, v2, o2):
        t = 0.5 * self.m[0] * (v1 @ v1) + 0.5 * self.i[0] * o1 ** 2
        if self.w[1] > 0.0:
            t += 0.5 * self.m[1] * (v2 @ v2) + 0.5 * self.i[1] * o2 ** 2
        return t

    def energy0(self):
        return self.energy(self.v[0], self.om[0], self.v[1], self.om[1])

    def impulse(self, pn, pt):
        return pn * self.n + pt * self.t


def reference(K, gn0, gt0, e, mu):
    """Routh's path integrated by solve_ivp: (Pn, Pt, path) with path 'sliding' (the slip never stops),
    'sticking' (it stops, then sticks) or 'reversed' (it stops, then slips the other way); without
    initial slip: 'sticking' or 'sliding'."""
    knn, knt, ktt = K[0, 0], K[0, 1], K[1, 1]
    sticks = abs(knt) <= mu * ktt
    mode = (1.0 if gt0 > 0 else -1.0) if gt0 != 0.0 else (0.0 if sticks else math.copysign(1.0, knt))
    path = "sliding" if mode != 0.0 else "sticking"

    def rhs(p, y, mode):
        s = -knt / ktt if mode == 0.0 else -mode * mu
        return [knn + knt * s, knt + ktt * s, s, y[0]]

    def slip_stop(p, y, mode):
        return y[1]
    slip_stop.terminal = True

    def compression_end(p, y, mode):
        return y[0]
    compression_end.terminal, compression_end.direction = True, 1.0

    wc = None

    def restitution_end(p, y, mode):
        return y[3] - (1.0 - e * e) * wc
    restitution_end.terminal, restitution_end.direction = True, 1.0

    scale = (abs(gn0) + abs(gt0)) / min(np.linalg.eigvalsh(K))
    p, y = 0.0, np.array([gn0, gt0, 0.0, 0.0])
    for _ in range(20):
        events = [compression_end if wc is None else restitution_end]
        if mode != 0.0:
            slip_stop.direction = -mode
            events.append(slip_stop)
        sol = solve_ivp(rhs, (p, p + 10.0 * scale), y, method="DOP853", rtol=1e-13,
                        atol=1e-14 * np.array([1.0, 1.0, scale, scale]) * (abs(gn0) + abs(gt0)), events=events,
                        args=(mode,))
        hit = [k for k, te in enumerate(sol.t_events) if len(te)]
        if not hit:
            p, y = sol.t[-1], sol.y[:, -1]
            continue
        k = min(hit, key=lambda k: sol.t_events[k][0])
        p, y = sol.t_events[k][0], sol.y_events[k][0].copy()
        if events[k] is slip_stop:
            y[1] = 0.0
            mode = 0.0 if sticks else math.copysign(1.0, knt)
            path = "sticking" if sticks else "reversed"
            continue
        if wc is None:  # compression ended
            y[0] = 0.0
            wc = y[3]
            if e == 0.0:
                return p, y[2], path
            continue
        return p, y[2], path
    raise AssertionError("the reference did not end")


def random_impacts(n=N_IMPACTS, seed=SEED):
    """Seeded random impacts (module docstring): (Bodies, e, mu) with approach g_n < -0.05 m/s."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        m1, m2 = rng.uniform(700.0, 3000.0, 2)
        i1, i2 = m1 * rng.uniform(0.9, 1.6) ** 2, m2 * rng.uniform(0.9, 1.6) ** 2
        barrier = rng.random() < 0.25
        if barrier:
            m2 = i2 = math.inf

        def arm():
            c, s = math.cos(h := rng.uniform(0, 2 * math.pi)), math.sin(h)
            x, y = rng.uniform(-2.5, 2.5), rng.uniform(-1.0, 1.0)
            return (c * x - s * y, s * x + c * y)
        r1, r2 = arm(), ((0.0, 0.0) if barrier else arm())
        phi = rng.uniform(0, 2 * math.pi)
        n_ = (math.cos(phi), math.sin(phi))
        v1, v2 = rng.uniform(-30, 30, 2), (np.zeros(2) if barrier else rng.uniform(-30, 30, 2))
        om1, om2 = rng.uniform(-3, 3), (0.0 if barrier else rng.uniform(-3, 3))
        b = Bodies(m1, i1, m2, i2, r1, r2, n_, v1, om1, v2, om2)
        gn, gt = b.nt(b.g0())
        if gn > 0.0:
            b = Bodies(m1, i1, m2, i2, r1, r2, (-n_[0], -n_[1]), v1, om1, v2, om2)
            gn, gt = b.nt(b.g0())
        if rng.random() < 0.1:  # no initial slip: body 1's velocity takes the slip, a round-off one is left
            v1 = v1 + (gt - rng.uniform(-1, 1) * 1e-12 * abs(gn)) * b.t
            b = Bodies(m1, i1, m2, i2, r1, r2, b.n, v1, om1, v2, om2)
            gn, gt = b.nt(b.g0())
        if gn > -0.05:
            continue
        e = 0.0 if rng.random() < 0.25 else rng.uniform(0.0, 0.6)
        out.append((b, e, rng.uniform(0.0, 1.2)))
    return out


def solve(b, e, mu, law):
    """The law's impulse (global) for the impact, with K from laws.impact_matrix."""
    k = impact_matrix(b.w[0], b.ii[0], b.w[1], b.ii[1], *b.r[0], *b.r[1], *b.n)
    gn, gt = b.nt(b.g0())
    pn, pt, kind = collision_impulse(*k, gn, gt, e, mu, law)
    return b.impulse(pn, pt), kind


@pytest.fixture(scope="module")
def cases():
    """Each random impact with the reference's impulse and path."""
    res = []
    for b, e, mu in random_impacts():
        gn, gt = b.nt(b.g0())
        no_slip = abs(gt) <= SLIP_TOL * abs(gn)
        pn, pt, path = reference(b.compliance(), gn, 0.0 if no_slip else gt, e, mu)
        if mu == 0.0 and path == "reversed":
            path = "sliding"  # no friction: the slip changes sign, the impulse does not notice
        res.append((b, e, mu, b.impulse(pn, pt), path, no_slip))
    return res


def test_routh_matches_the_reference(cases):
    """Routh's delta-V (impulse / mass) within REF_REL of the reference's, its yaw-rate changes within REF_REL
    of the size of a yaw-rate change |r| |Π| / I; the kind says the reference's path."""
    paths = {}
    for b, e, mu, p_ref, path, _ in cases:
        p, kind = solve(b, e, mu, ROUTH)
        assert np.linalg.norm(p - p_ref) <= REF_REL * np.linalg.norm(p_ref), (b.__dict__, e, mu, p, p_ref)
        d_ref, d = b.after(p_ref), b.after(p)
        for q, om in ((0, 1), (1, 3)):
            size = np.linalg.norm(b.r[q]) * np.linalg.norm(p_ref) * b.ii[q]
            assert abs(d[om] - d_ref[om]) <= REF_REL * size + 1e-15
        assert kind == {"sliding": 1, "sticking": 0, "reversed": REVERSED}[path], (path, kind)
        paths[path] = paths.get(path, 0) + 1
    # the sample covers every path
    assert min(paths.get(k, 0) for k in ("sliding", "sticking", "reversed")) >= 50, paths


@pytest.mark.parametrize("law", [KUDLICH_SLIBAR, BRACH, ROUTH])
def test_no_impact_creates_energy(cases, law):
    for b, e, mu, *_ in cases:
        p, _ = solve(b, e, mu, law)
        t0, t1 = b.energy0(), b.energy(*b.after(p))
        assert t1 <= t0 * (1.0 + ENERGY_REL), (law, b.__dict__, e, mu, t1 / t0)


def test_routh_equals_the_other_laws_where_slip_never_stops_and_where_it_sticks_plastically(cases):
    """One slip phase (the slip never stops, or there is none at the start): the normal velocity is linear
    in the normal impulse, so the energetic, Newton's and Poisson's coefficients coincide and Routh is the
    sliding (or, sticking without initial slip, the full) impact of both laws. The slip stops and sticks
    with e = 0: every law ends with g' = 0."""
    n_equal = 0
    for b, e, mu, _, path, no_slip in cases:
        if not (path == "sliding" or (path == "sticking" and (e == 0.0 or no_slip))):
            continue
        p, _ = solve(b, e, mu, ROUTH)
        for law in (KUDLICH_SLIBAR, BRACH):
            q, _ = solve(b, e, mu, law)
            assert np.linalg.norm(q - p) <= EQUAL_REL * np.linalg.norm(p), (law, path, b.__dict__, e, mu)
        n_equal += 1
    assert n_equal >= 500


def test_every_slip_reversal_is_flagged(cases):
    """Kudlich-Slibar and Brach flag exactly the impacts whose slip stops and reverses on the reference's
    path (friction > 0; no flag without initial slip), and their impulse there differs from Routh's; and, as an
    overshoot, exactly those whose slip stops and sticks on the reference's path where the law's own sliding impulse
    reverses the slip (its g'_t, by the post-impact formulas here, of the other sign than g_t beyond SLIP_TOL
    g_n): its friction against the initial slip runs on past the stop (a fuzzer, 2026-11-27: unflagged before)."""
    n_rev, n_over = 0, {KUDLICH_SLIBAR: 0, BRACH: 0}
    for b, e, mu, p_ref, path, no_slip in cases:
        k = impact_matrix(b.w[0], b.ii[0], b.w[1], b.ii[1], *b.r[0], *b.r[1], *b.n)
        gn, gt = b.nt(b.g0())
        for law in (KUDLICH_SLIBAR, BRACH):
            pn, pt, kind, rev, rpn, rpt = checked_impulse(*k, gn, gt, e, mu, law)
            assert (rev == SLIP_REVERSES) == (path == "reversed"), (law, path, b.__dict__, e, mu)
            gt_after = b.nt(b.g(*b.after(b.impulse(pn, pt))))[1]
            over = path == "sticking" and not no_slip and kind == SLIDING and gt_after * gt < 0.0 \
                and abs(gt_after) > SLIP_TOL * abs(gn)
            assert (rev == SLIP_OVERSHOOT) == over, (law, path, kind, gt, gt_after, e, mu)
            n_over[law] += over
            assert np.linalg.norm(b.impulse(rpn, rpt) - p_ref) <= REF_REL * np.linalg.norm(p_ref)
        n_rev += path == "reversed"
    print(f"slip-reversing impacts flagged: {n_rev} of {len(cases)}; overshoots {n_over}")
    assert n_rev >= 50 and n_over[KUDLICH_SLIBAR] >= 50  # measured: 70 reversals; 69 overshoots, none in brach


def test_central_impact_is_newton_and_poisson():
    """Central impact (K_nt = 0, no slip): g'_n = -e g_n, Pt = 0, as the other laws."""
    for e in (0.0, 0.3, 1.0):
        k = impact_matrix(1 / 1500, 1 / 2500, 1 / 1300, 1 / 2000, 1.9, 0.0, -2.1, 0.0, 1.0, 0.0)
        pn, pt, kind = collision_impulse(*k, -10.0, 0.0, e, 0.4, ROUTH)
        assert kind == 0 and pt == 0.0
        assert pn == pytest.approx((1 + e) * 10.0 / (1 / 1500 + 1 / 1300), rel=1e-14)


def test_no_slip_tolerance_is_symmetric():
    """|g_t| <= SLIP_TOL |g_n| is no slip for every law: +-1e-16 of tangential velocity (a contact plane
    at 90 or -90 deg) gives the same impulse; beyond the tolerance the slip counts."""
    k = impact_matrix(1 / 1500, 1 / 2500, 1 / 1300, 1 / 2000, 1.9, 0.7, -0.3, 1.1, 1.0, 0.0)
    assert abs(k[2]) > 0.05 * k[1]  # mu = 0.05 cannot stick: the impacts slide
    for law in (KUDLICH_SLIBAR, BRACH, ROUTH):
        a = collision_impulse(*k, -10.0, 1e-16, 0.1, 0.05, law)
        b = collision_impulse(*k, -10.0, -1e-16, 0.1, 0.05, law)
        assert a == b
        c = collision_impulse(*k, -10.0, 1e-6, 0.1, 0.05, law)
        d = collision_impulse(*k, -10.0, -1e-6, 0.1, 0.05, law)
        if law == ROUTH:  # a slip of 1e-6 stops at once and follows K_nt: continuous through zero slip
            assert c[:2] == pytest.approx(a[:2], rel=1e-6) and d[:2] == pytest.approx(a[:2], rel=1e-6)
        else:  # friction against the initial slip: the sign follows it
            assert (c[1] > 0) != (d[1] > 0)


def oblique_front_into_side(make_scene, law, mu=0.45):
    """A 1500 kg saloon at 50 km/h, heading -75 deg, its front-left corner into the left side of a 1300 kg Clio
    1.1 m behind its CG, the Clio driving at 15 km/h; restitution 0; contact plane along the Clio's side.
    Sticking needs mu 0.50: at 0.45 the slip stops and reverses."""
    return make_scene(vehicles=[{"vehicle": "saloon", "x": -2.521, "y": 2.584, "heading": -75.0, "speed": 50.0,
                                 "overrides": {"mass": 1500.0, "yaw_inertia": 2846.5}},
                                {"speed": 15.0, "overrides": {"mass": 1300.0, "yaw_inertia": 1475.5}}],
                      impact={"restitution": 0.0, "friction": mu, "law": law, "point": [-1.1, 0.82],
                              "plane_angle": 0.0}, duration=3.0)


def test_a_simulated_slip_reversal_is_flagged_and_warned(make_scene, impulse_model):
    """The impact row says slip_reversed for Kudlich-Slibar and Brach, the outcome warns with their delta-V
    beside Routh's (and names law = "routh"); Routh's own row says kind reversed, without a warning; with
    friction enough to stick nothing is flagged."""
    routh = impulse_model.simulate(oblique_front_into_side(make_scene, "routh"))
    r = routh.impacts
    assert list(r.kind[:2]) == ["reversed", "reversed"] and r.slip_reversed[:2].all()
    assert not any("routh" in w for w in routh.warnings)
    for law in ("kudlich-slibar", "brach"):
        out = impulse_model.simulate(oblique_front_into_side(make_scene, law))
        assert out.impacts.slip_reversed[:2].all()
        warn = [w for w in out.warnings if w.startswith("impact 1 (V1-V2")]
        assert len(warn) == 1 and 'law = "routh"' in warn[0], out.warnings
        dv = out.impacts.delta_v.iloc[0]
        assert f"V1 {dv:.1f} instead of {r.delta_v.iloc[0]:.1f} km/h" in warn[0]
        assert abs(dv / r.delta_v.iloc[0] - 1.0) > 0.2  # this geometry: -35 %
    stick = impulse_model.simulate(oblique_front_into_side(make_scene, "kudlich-slibar", mu=0.6))
    assert not stick.impacts.slip_reversed.any() and not any("routh" in w for w in stick.warnings)


def test_a_simulated_sliding_overshoot_is_warned(make_scene, impulse_model):
    """A fuzzer's impact (2026-11-27): an F-150 and a Clio at a given point, e = 0.2664, contact friction 0.7968.
    On Routh's path the slip stops and sticks; Kudlich-Slibar calls it sliding and its friction against the initial
    slip runs on past the stop, reversing the slip: its row is no slip reversal (Routh's path does not reverse),
    the outcome warns with its delta-V beside Routh's (V2 3.8 instead of 3.6 km/h: +7 %, 11 deg off). It was
    silent before."""
    def scene(law):
        return make_scene(vehicles=[{"vehicle": "f150_1998", "heading": -111.62934415860818,
                                     "speed": 17.537323068424215, "yaw_rate": 4.246989776232567},
                                    {"vehicle": "clio", "x": -1.131041111107672, "y": -0.9227368863394123,
                                     "heading": -61.567075803795696, "speed": 18.260056423733296}],
                          impact={"restitution": 0.2664, "friction": 0.7968, "law": law,
                                  "point": [-0.6164265517840444, -2.5309743268906413],
                                  "plane_angle": 39.71176756084904}, duration=3.0)
    routh = impulse_model.simulate(scene("routh")).impacts
    assert list(routh.kind[:2]) == ["full", "full"]
    out = impulse_model.simulate(scene("kudlich-slibar"))
    assert list(out.impacts.kind[:2]) == ["sliding", "sliding"] and not out.impacts.slip_reversed.any()
    warn = [w for w in out.warnings if w.startswith("impact 1 (V1-V2")]
    assert len(warn) == 1 and "stops and sticks" in warn[0] and 'law = "routh"' in warn[0], out.warnings
    dv = out.impacts.delta_v.iloc[1]
    assert f"V2 {dv:.1f} instead of {routh.delta_v.iloc[1]:.1f} km/h" in warn[0]
    assert dv / routh.delta_v.iloc[1] - 1.0 == pytest.approx(0.07, abs=0.01)
