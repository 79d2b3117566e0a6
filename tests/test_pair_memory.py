"""A pair's crush memory across its contact episodes (docs/physics.md §13a "Crush memory"): kept while the struck
faces stay the same, the faces of a re-touch chosen by the approach as at a first touch.

Until 2026-11-28 the faces were chosen again at every evaluation while the pair was apart, by the touch point's
rule (the nearest face in proportion), which differs from the approach's at rounded corners: two saloons head-on
at a 0.26 m overlap latched front / front at the touch, were taken for left / left once apart, their memory was
forgotten, and the re-touch met fresh fronts (a review, 2026-11-28: 2.4 times the energy over 0.35 m of crush).

Reference written here: the pair's law by hand (docs/physics.md §13a), unloaded from its largest crush C_m along
slope B_s / e^2 to the permanent set C_m (1 - e^2), where no strip bears: a re-touch bears nothing below it."""
import math

import numpy as np
import pytest

from crashlab.models.common import chassis_contact as C
from crashlab.models.common.contact_episodes import track_peak
from crashlab.models.common.contact_force import FRICTION_V0, FRICTION_V1, FRICTION_VS

SH = np.array([2.38, 0.916, 0.25, 0.5, 0.5, 0.0, 0.0])      # the library saloon's chassis (2 / eps = 4)
STR = np.array([48e3, 590e3, 1.832, 24e3, 300e3, 1.832, 30e3, 370e3, 4.7])
E = 0.1


def _arrays():
    PP = C.pair_table(2, 0, 1e6, 1.5, np.array([STR, STR]), [1500.0, 1500.0])
    return C.contact_arrays(np.array([SH, SH]), PP, np.zeros((0, 5)), 2)


def _evaluate(CT, x2, y2, v):
    """V1 at the origin heading +x at v, V2 at (x2, y2) heading -x at v (closing at 2 v; v < 0: parting)."""
    Y = np.zeros((2, 13))
    for k, (x, y, h, vx) in enumerate(((0.0, 0.0, 0.0, v), (x2, y2, math.pi, -v))):
        Y[k, :7] = [x, y, 0.5, math.cos(h / 2), 0.0, 0.0, math.sin(h / 2)]
        Y[k, 7] = vx
    CSH, BOXR, BOXA, BOXE, PP, PST, PSG, FX, BPC, OUT, FM = CT
    C.contacts(Y, 7, CSH, BOXR, BOXA, BOXE, PP, PST, PSG[0], FX, BPC, OUT, FM, 1.5, 0.0, 0.3, 0.0, FRICTION_V0,
               FRICTION_V1, FRICTION_VS, 1e-3, float(C.LAW_STRUCTURE), E)
    return PSG[0, 0].copy(), -FX[0, 0]


def _press(CT, touch, y2, depths):
    """Open an episode at the touch and press V2 in by `depths` (accepted evaluations); the force at each."""
    PST = CT[5]
    _evaluate(CT, touch - 1e-4, y2, 10.0)
    PST[0, C.S_ACT] = C.IN_CONTACT
    forces = []
    for d in depths:
        out, f = _evaluate(CT, touch - d, y2, 10.0)
        track_peak(PST, 0, out, CT[4], CT[10])
        forces.append(f)
    PST[0, C.S_ACT] = C.NONE                                 # the episode closes
    return np.array(forces)


@pytest.mark.parametrize("overlap", [0.26, 1.0])
def test_a_retouch_after_parting_meets_the_crushed_fronts(overlap):
    y2 = 2.0 * SH[1] - overlap
    lo, hi = 3.0, 6.0                                         # V2's x at the first touch (bisection on the gap)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _evaluate(_arrays(), mid, y2, 10.0)[0][C.G_GAP] < 0 else (lo, mid)
    CT = _arrays()
    PST = CT[5]
    _press(CT, lo, y2, np.arange(0.01, 0.305, 0.01))
    faces, cm = (PST[0, C.S_FACE_I], PST[0, C.S_FACE_J]), PST[0, C.S_CMAX]
    assert faces == (0, 0) and cm == pytest.approx(0.30, abs=1e-3)          # front / front, pressed 0.30 m
    for dx in np.arange(0.05, 0.6, 0.01):                                    # parting, 5-60 cm apart
        _evaluate(CT, lo + dx, y2, -1.0)
    again = _press(CT, lo, y2, np.arange(0.01, 0.355, 0.01))
    assert (PST[0, C.S_FACE_I], PST[0, C.S_FACE_J]) == faces and PST[0, C.S_CMAX] == pytest.approx(0.35, abs=1e-3)
    depths = np.arange(0.01, 0.355, 0.01)
    permanent = cm * (1.0 - E * E)                            # 0.297 m: nothing bears below it
    assert np.all(again[depths < permanent - 0.005] == 0.0), again
    assert again[-1] > 0.0
