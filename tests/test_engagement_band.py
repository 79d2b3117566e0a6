"""The engagement's hysteresis (docs/physics.md §13a "Engagement"): in an open episode an engaged pair (crush along
the struck faces' normal) keeps that normal while its crush along it is within ENGAGED_BAND below the shapes'
overlap, and a pair on the overlap's normal engages once it is ENGAGED_BAND above. Until 2026-11-28 the two switched
at equality: a pair pressed at rest there had its normal flip 65 deg on round-off, and exudyn's load iteration never
settled (a saloon pushing a locked Clio on a wet road, a random probe scene: "the contact loads did not settle")."""
import math

import numpy as np
import pytest

import crashlab
from crashlab.models.common import chassis_contact as C
from crashlab.models.common.contact_episodes import sync_crush
from crashlab.models.common.contact_force import FRICTION_V0, FRICTION_V1, FRICTION_VS
from crashlab.scene_file import scene_from_dict

E, B = 0.1, 590e3
SH = np.array([2.0, 0.8, 0.25, 0.04, 0.04, 0.0, 0.0])        # a nearly box-shaped chassis
STR = np.array([40e3, B, 1.6, 40e3, B, 1.6, 40e3, B, 4.0])


def _state(x2, y2, psi):
    """V1 at the origin heading +x; V2 ahead at (x2, y2) turned by psi (V1's front meets V2's rear), at rest."""
    Y = np.zeros((2, 13))
    Y[0, :7] = [0.0, 0.0, 0.5, 1.0, 0.0, 0.0, 0.0]
    Y[1, :7] = [x2, y2, 0.5, math.cos(psi / 2), 0.0, 0.0, math.sin(psi / 2)]
    return Y


def _evaluate(Y, CT, accept=True):
    """One evaluation of the pair's contact; kept as an integrator keeps an accepted one (sync_crush)."""
    CSH, BOXR, BOXA, BOXE, PP, PST, PSG, FX, BPC, OUT, FM = CT
    C.contacts(Y, 7, CSH, BOXR, BOXA, BOXE, PP, PST, PSG[0], FX, BPC, OUT, FM, 1.5, 0.0, 0.3, 0.0, FRICTION_V0,
               FRICTION_V1, FRICTION_VS, 1e-3, float(C.LAW_STRUCTURE), E)
    out = PSG[0, 0].copy()
    if accept:
        sync_crush(PST, 0, out)
    # engaged or not; the engaged crush less the overlap (0 on the overlap's normal); the normal's angle [deg]
    return out[C.G_ENG], out[C.G_RAW] + out[C.G_GAP], math.degrees(out[C.G_TH])


def test_an_engaged_pair_keeps_its_normal_within_the_band_and_engages_beyond_it():
    PP = C.pair_table(2, 0, 1e6, 1.5, np.array([STR, STR]), [1200.0, 1200.0])
    CT = C.contact_arrays(np.array([SH, SH]), PP, np.zeros((0, 5)), 2)
    y, psi = 1.3, 0.2                                    # 0.3 m of lateral overlap, V2 turned 11.5 deg
    _evaluate(_state(3.93, y, psi), CT)                  # the first touch latches V1's front and V2's rear
    CT[5][0, C.S_ACT] = 1.0                              # the episode opens (contact_episodes.open_episode)
    for x in np.arange(3.93, 3.81, -0.002):              # pressed along x: engaged, its crush above the overlap
        eng, above, th = _evaluate(_state(x, y, psi), CT)
    assert eng == 1.0 and above > C.ENGAGED_BAND
    # then V2 slides 80 deg off the x axis and back: along the overlap's normal the overlap grows faster than the
    # crush along the faces' normal
    s = np.arange(0.0, 0.06, 0.0005)
    path = [(x - d * math.cos(math.radians(80)), y - d * math.sin(math.radians(80))) for d in s]
    hist = [_evaluate(_state(px, py, psi), CT) for px, py in path + path[::-1]]
    switches = [k for k in range(1, len(hist)) if hist[k][0] != hist[k - 1][0]]
    assert len(switches) == 2
    out, back = switches
    # engaged down to the band below the overlap (failed before: engaged only at or above it), then on the
    # overlap's own normal, 5.7 deg away
    assert -C.ENGAGED_BAND <= hist[out - 1][1] < -0.5 * C.ENGAGED_BAND
    assert hist[out][0] == 0.0 and hist[out][1] == 0.0 and abs(hist[out][2] - hist[out - 1][2]) > 5.0
    # engaged again only from the band above it, at another place on the way back (the relay's width)
    assert C.ENGAGED_BAND <= hist[back][1] < 1.5 * C.ENGAGED_BAND
    assert len(path) - 1 - (back - len(path)) < out - 5
    # an evaluation not kept does not move the choice: the same configuration evaluated again gives the same normal
    px, py = path[(out + (len(path) - 1 - (back - len(path)))) // 2]
    first = _evaluate(_state(px, py, psi), CT, accept=False)
    assert _evaluate(_state(px, py, psi), CT, accept=False) == first


def test_exudyn_settles_a_saloon_pushing_a_locked_clio():
    """The probe's scene (rear-end at 25 / 11 km/h, 0.42 m of overlap, road friction 0.1): the saloon pushes the
    locked Clio, their engaged crush equal to their overlap from 2.33 s; exudyn's load iteration flipped between
    the two normals and failed (93 steps at the shortest step); multibody ran it."""
    pytest.importorskip("exudyn")
    scene = scene_from_dict({
        "duration": 2.5, "road": {"friction": 0.1}, "impact": {"restitution": 0.1, "friction": 0.1},
        "vehicles": [{"name": "V1", "vehicle": "saloon", "speed": 25.0},
                     {"name": "V2", "vehicle": "clio", "x": 4.871, "y": 1.3144640686792373, "speed": 11.0,
                      "wheels": "locked"}]})
    out = crashlab.simulate(scene, model="exudyn")
    assert out.outcome_ok, out.warnings
    assert not any("did not settle" in w for w in out.warnings)
    ref = crashlab.simulate(scene, model="multibody")
    # the second opinion: the pushed Clio where multibody puts it, within 0.1 m
    assert np.hypot(*(out.rest_si[1, :2] - ref.rest_si[1, :2])) < 0.1
