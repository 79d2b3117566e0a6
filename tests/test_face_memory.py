"""The crush structures' face memory (docs/physics.md §13a "Face memory"): each vehicle keeps its own largest crush
along each struck face, and every partner meets it (until 2026-11-27 the memory belonged to a pair: a face crushed
by one car met the next as new, crushed again from its undeformed outline).

References written here: two CRASH3 structures in series (the same force f per unit width on both), one fresh (its
loading line f = B c) and one crushed to m before (its unloading line, slope B / e^2 from (m, B m) down to the
permanent set m (1 - e^2), then its loading line again): at total crush C the force is 0 up to the permanent set,
B (C - m (1 - e^2)) / (1 + e^2) while the crushed one reloads (C <= 2 m, equal B), then B C / 2."""
import math

import numpy as np
import pytest

from crashlab.models.common import chassis_contact as C
from crashlab.models.common import crush_structure as CS
from crashlab.models.common.contact_episodes import remember_faces, track_peak
from crashlab.models.common.contact_force import FRICTION_V0, FRICTION_V1, FRICTION_VS

B = 590e3                                                     # N/m^2, both fronts
E = 0.1
SH = np.array([2.0, 0.8, 0.25, 0.04, 0.04, 0.0, 0.0])        # a nearly box-shaped chassis (2 / eps = 50)
STR = np.array([40e3, B, 1.6, 40e3, B, 1.6, 40e3, B, 4.0])


def _series_with_one_crushed(c, m, e=E, b=B):
    """Force per unit width at total crush c of a fresh structure against one crushed to m (equal B)."""
    p = m * (1.0 - e * e)
    if c <= p:
        return 0.0
    return b * (c - p) / (1.0 + e * e) if c <= 2.0 * m else b * c / 2.0


@pytest.mark.parametrize("c", [0.05, 0.19, 0.21, 0.25, 0.35, 0.45, 0.7])
def test_strip_force_against_the_series_by_hand(c):
    f, c1, c2 = CS.strip_force(c, 0.0, 0.2, E, B, B)
    assert f == pytest.approx(_series_with_one_crushed(c, 0.2), rel=1e-12, abs=1e-9)
    if f > 0.0:
        assert c1 == pytest.approx(f / B, rel=1e-12)              # the fresh one on its loading line
        assert c1 + c2 == pytest.approx(c, rel=1e-12)


def test_strip_force_of_one_pairs_memory_is_the_pairs_law():
    """Memories shared as one pair's loading shares its crush (m_q = m B_s / B_q) give the pair's law."""
    rng = np.random.default_rng(7)
    for _ in range(2000):
        b1, b2 = rng.uniform(1e5, 1e6, 2)
        e, m, c = rng.uniform(0.02, 0.9), rng.uniform(0.0, 1.0), rng.uniform(0.0, 1.5)
        bs = b1 * b2 / (b1 + b2)
        # the pair's law written out: loading B_s c beyond m, else the unloading line through (m, B_s m)
        ref = bs * c if c >= m else max(bs * m - bs / e ** 2 * (m - c), 0.0)
        assert CS.strip_force(c, m * bs / b1, m * bs / b2, e, b1, b2)[0] == pytest.approx(ref, rel=1e-9, abs=1e-6)


def _state(x2):
    """V1 at the origin heading +x, V2 at (x2, 0) heading -x (front to front), both at rest."""
    Y = np.zeros((2, 13))
    Y[0, :7] = [0.0, 0.0, 0.5, 1.0, 0.0, 0.0, 0.0]
    Y[1, :7] = [x2, 0.0, 0.5, 0.0, 0.0, 0.0, 1.0]
    return Y


def _arrays():
    PP = C.pair_table(2, 0, 1e6, 1.5, np.array([STR, STR]), [1200.0, 1200.0])
    return C.contact_arrays(np.array([SH, SH]), PP, np.zeros((0, 5)), 2)


def _evaluate(Y, CT):
    CSH, BOXR, BOXA, BOXE, PP, PST, PSG, FX, BPC, OUT, FM = CT
    C.contacts(Y, 7, CSH, BOXR, BOXA, BOXE, PP, PST, PSG[0], FX, BPC, OUT, FM, 1.5, 0.0, 0.3, 0.0, FRICTION_V0,
               FRICTION_V1, FRICTION_VS, 1e-3, float(C.LAW_STRUCTURE), E)
    return PSG[0, 0].copy(), FX.copy()


def _force(depth, memory):
    """The contact force on V1 along -x with V2 pushed `depth` beyond the first touch of the undeformed shapes,
    V2's front crushed to `memory` all across before (its face memory), the pair itself fresh; and the outputs."""
    CT = _arrays()
    CT[10][1, 0:C.N_FACE_BIN] = memory                      # V2's front (face 0), every bin
    x0 = 2.0 * SH[0]                                          # the noses touch
    _evaluate(_state(x0), CT)                                 # the faces latched at the touch
    CT[5][0, C.S_ACT] = 1.0                                   # the episode opens (contact_episodes.open_episode)
    out, FX = _evaluate(_state(x0 - depth), CT)
    return -FX[0, 0], out


@pytest.mark.parametrize("depth", [0.1, 0.3, 0.45, 0.6])
def test_a_crushed_face_meets_a_new_partner_crushed(depth):
    """V2's front crushed to 0.2 m by an earlier partner: against a fresh V1 it bears nothing until the pair's
    crush passes its permanent set, then reloads along its unloading line, then both crush on (the reference by
    hand with the memory less FACE_MEMORY_TOL, integrated over the width by the fresh pair's own force: the same
    profile, so the ratio is the reference's); before the face memory the pair met it as new: B C / 2 from the
    first touch."""
    fresh, out0 = _force(depth, 0.0)
    crushed, out = _force(depth, 0.2)
    assert fresh == pytest.approx(out0[C.G_WIDTH] * B * depth / 2.0, rel=0.03)   # a nearly flat face
    m = 0.2 - C.FACE_MEMORY_TOL  # the face memory counts beyond the pair's own (none here) less its resolution
    ref = _series_with_one_crushed(depth, m) / (B * depth / 2.0)
    assert crushed == pytest.approx(ref * fresh, rel=0.03, abs=1e-3 * fresh)
    assert (out[C.G_DEL] > 0.0) == (depth > m * (1.0 - E * E))


def test_the_memory_keeps_each_bins_least_crush_and_the_largest_over_time():
    """remember_faces: per bin the least crush of the strips on it in one evaluation and, from FM_ANY, their
    largest, kept on the bin and its neighbours on the same face (not across a face's edge: bin 31 is the front's
    last, 32 the rear's first), each the largest over evaluations; a barrier (j >= nv) has none (a third row, beyond
    nv, stays untouched)."""
    FM3 = np.zeros((3, C.N_FM))
    FM = FM3[:2]
    A = C.FM_ANY
    out = np.zeros(C.N_PSG)
    out[C.G_NS] = 3
    out[C.G_STRIP:C.G_STRIP + 12] = [5, 0.30, 40, 0.1, 5, 0.20, 40, 0.05, 6, 0.25, -1, -1.0]
    remember_faces(FM, 0, 1, out)
    assert FM[0, 5] == pytest.approx(0.20) and FM[0, 6] == pytest.approx(0.25)
    assert FM[0, A + 4:A + 8] == pytest.approx([0.30, 0.30, 0.30, 0.25])
    assert FM[1, 40] == pytest.approx(0.05) and FM[1, A + 39:A + 42] == pytest.approx([0.1, 0.1, 0.1])
    assert np.count_nonzero(FM) == 10
    out[C.G_STRIP:C.G_STRIP + 12] = [31, 0.40, 40, 0.2, 31, 0.40, 40, 0.2, 6, 0.10, -1, -1.0]
    remember_faces(FM, 0, 2, out)                             # 2 >= nv: the partner is a barrier
    assert FM[0, 31] == pytest.approx(0.40) and FM[0, A + 30:A + 33] == pytest.approx([0.40, 0.40, 0.0])
    assert FM[1, 40] == pytest.approx(0.05) and FM[0, A + 6] == pytest.approx(0.30)
    assert math.isclose(FM[:, :A].sum(), 0.9) and math.isclose(FM[:, A:].sum(), 2.25) and not FM3[2].any()


def test_a_crushed_face_reloads_as_a_new_partner_presses_on():
    """The same pair pressed on in steps, each evaluation kept (contact_episodes.track_peak, as the integrators
    do): V2's front crushed to 0.2 m before reloads along its unloading line while V1's fresh front loads, then both
    crush on. With the pair's total crush shared as one loading shares it (the first build, a reviewer's probe),
    V1 was given half of V2's old dent as its own memory: both on their unloading lines, the contact force-free from
    0.18 to 0.33 m (10.7 against about 24 kJ of work to 0.40 m). Each structure's own largest crush at the pair's
    deepest strip (S_CM1, S_CM2) keeps the reference by hand (its ratio to the fresh pair's force, as above)."""
    def run(memory):
        CT = _arrays()
        CT[10][1, 0:C.N_FACE_BIN] = memory
        x0 = 2.0 * SH[0]
        _evaluate(_state(x0), CT)
        CT[5][0, C.S_ACT] = 1.0
        forces = []
        for depth in np.arange(0.01, 0.61, 0.01):
            out, FX = _evaluate(_state(x0 - depth), CT)
            track_peak(CT[5], 0, out, CT[4], CT[10])
            forces.append((depth, -FX[0, 0]))
        return forces
    m = 0.2 - C.FACE_MEMORY_TOL
    fresh_run, crushed_run = run(0.0), run(0.2)
    scale = 0.01 * max(f for _, f in fresh_run)  # the profile's corners: about 1 kN through the steep reload
    work = work_ref = 0.0
    for (depth, fresh), (_, crushed) in zip(fresh_run, crushed_run):
        ref = _series_with_one_crushed(depth, m) / (B * depth / 2.0) * fresh
        assert crushed == pytest.approx(ref, rel=0.02, abs=scale), (depth, crushed, ref)
        work, work_ref = work + 0.01 * crushed, work_ref + 0.01 * ref
    assert work == pytest.approx(work_ref, rel=0.02)


@pytest.mark.parametrize("depth", [0.1, 0.3, 0.6])
def test_a_place_never_crushed_bears_from_its_first_touch_whatever_the_pairs_memory(depth):
    """The pair's own memory is measured from its deepest strip on the current geometry: after a pair turns, strips
    on places that never touched came out as crushed as the deepest (a probe, 2026-11-28: two saloons spinning
    together after a head-on passed 1.48 m into fresh fronts without a force, then met 625 kN). Here the pair's
    memory says 0.5 m (as if crushed elsewhere) and neither front was ever crushed (both face memories empty): the
    fronts bear as fresh ones beyond the memory's resolution (FACE_MEMORY_TOL each: then the series' loading line,
    B C / 2 per unit width, the fresh pair's own force), where the pair's memory alone gave nothing below its
    permanent set 0.5 (1 - e^2) (0.6 m: beyond the memory, both on their loading lines, passes either way)."""
    fresh, _ = _force(depth, 0.0)
    CT = _arrays()
    PST = CT[5]
    x0 = 2.0 * SH[0]
    _evaluate(_state(x0), CT)
    PST[0, C.S_CMAX], PST[0, C.S_CM1], PST[0, C.S_CM2] = 0.5, 0.25, 0.25
    PST[0, C.S_ACT] = 1.0
    out, FX = _evaluate(_state(x0 - depth), CT)
    ref = fresh * (1.0 if depth >= 2.0 * C.FACE_MEMORY_TOL else 0.0)
    assert -FX[0, 0] == pytest.approx(ref, rel=1e-6) and out[C.G_DEL] > 0.0
    assert fresh == pytest.approx(out[C.G_WIDTH] * B * depth / 2.0, rel=0.03)
