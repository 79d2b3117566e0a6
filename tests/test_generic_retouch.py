"""The generic contact law's damping at a re-touch within an episode (docs/physics.md §13, §15 "Episodes and
pushes"): an episode lasts until the pair is SEPARATION apart, so a pair may touch again within it (a push after a
rear-end, a bounce). F_N = K delta^n (1 + chi delta_dot / delta_dot0) gives the scene's restitution for an impact
whose approach speed is delta_dot0; a re-touch is an impact of its own approach speed. Before, it kept the
episode's first approach speed: a re-touch at a tenth of it had a tenth of the damping (nearly elastic).

Reference written here: the hysteresis law in closed form with the touch's own approach speed, evaluated at the
penetration and normal velocity the contact reports."""
import sys
from pathlib import Path

import numpy as np
import pytest

from crashlab.models.common import chassis_contact as C
from crashlab.models.common import contact_episodes as EP
from crashlab.models.common.contact_force import FRICTION_V0, FRICTION_V1, FRICTION_VS

sys.path.insert(0, str(Path(__file__).parent))
from test_contact_engagement import SH, STR  # noqa: E402

K, N, CHI, V_MIN = 1e6, 1.5, 0.9, 1e-3
DEPTH = 0.02     # m: the fronts pressed into each other
IMPACT = 10.0    # m/s: the episode's first approach speed


def _arrays():
    PP = C.pair_table(2, 0, K, N, np.array([STR, STR]), [1500.0, 1500.0])
    return C.contact_arrays(np.array([SH, SH]), PP, np.zeros((0, 5)), 2)


def _head_on(x2, closing):
    """V1 at the origin heading +x, V2 at x2 heading -x (aligned), V2 moving towards V1 at `closing`."""
    Y = np.zeros((2, 13))
    Y[0, :7] = [0.0, 0.0, 0.5, 1.0, 0.0, 0.0, 0.0]
    Y[1, :7] = [x2, 0.0, 0.5, 0.0, 0.0, 0.0, 1.0]
    Y[1, 7] = -closing
    return Y


def _evaluate(Y, CT):
    CSH, BOXR, BOXA, BOXE, PP, PST, PSG, FX, BPC, OUT, FM = CT
    C.contacts(Y, 7, CSH, BOXR, BOXA, BOXE, PP, PST, PSG[0], FX, BPC, OUT, FM, N, CHI, 0.0, 0.0, FRICTION_V0,
               FRICTION_V1, FRICTION_VS, V_MIN, float(C.LAW_GENERIC), 0.1)
    return PSG[0, 0].copy()


def _law(delta, delta_dot, delta_dot0):
    """K_eff delta^n (1 + chi delta_dot / delta_dot0): two equal Hertz springs in series, K (1/2)^n."""
    return K * 0.5 ** N * delta ** N * (1.0 + CHI * delta_dot / delta_dot0)


def _x2_at_depth():
    """x of V2 at which the aligned fronts overlap by DEPTH (2 a less the depth)."""
    return 2.0 * SH[0] - DEPTH


@pytest.mark.parametrize("retouch", [1.0, 0.3])
def test_a_retouch_is_damped_for_its_own_approach_speed(retouch):
    """Episode opened at 10 m/s, its contact ended (S_ACT ENDED, the pair within SEPARATION): the re-touch at
    `retouch` m/s is damped with its own approach speed in the trial stages, and once the accepted step marks it in
    contact the law keeps that speed while the episode's record keeps 10 m/s."""
    CT = _arrays()
    PST = CT[5]
    EP.open_episode(PST, 0, 0.0, IMPACT, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    PST[0, C.S_ACT] = EP.ENDED
    out = _evaluate(_head_on(_x2_at_depth(), retouch), CT)
    delta, dd = out[C.G_DEL], out[C.G_DDOT]
    assert delta == pytest.approx(DEPTH, rel=1e-3)
    assert dd == pytest.approx(retouch, rel=1e-9)
    assert out[C.G_FN] == pytest.approx(_law(delta, dd, retouch), rel=1e-9)
    # the accepted step: the re-touch continues the episode, in contact again
    EP.episode_step(np.zeros((4, EP.N_IMP)), 0, CT[4], PST, 0, 0.1, 0.1, 0.1, delta, -delta, dd,
                    (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    assert PST[0, C.S_ACT] == EP.IN_CONTACT
    assert PST[0, C.S_DD0] == IMPACT
    out = _evaluate(_head_on(_x2_at_depth(), 0.5 * retouch), CT)  # later in the re-touch: slower
    assert out[C.G_FN] == pytest.approx(_law(out[C.G_DEL], out[C.G_DDOT], retouch), rel=1e-9)
    assert out[C.G_FN] != pytest.approx(_law(out[C.G_DEL], out[C.G_DDOT], IMPACT), rel=1e-3)


def test_the_first_touch_keeps_its_approach_speed():
    """An episode in contact since its onset at 10 m/s: the law's delta_dot0 is 10 m/s (unchanged)."""
    CT = _arrays()
    EP.open_episode(CT[5], 0, 0.0, IMPACT, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    out = _evaluate(_head_on(_x2_at_depth(), 4.0), CT)
    assert out[C.G_FN] == pytest.approx(_law(out[C.G_DEL], out[C.G_DDOT], IMPACT), rel=1e-9)


def test_a_contact_that_goes_on_past_push_time_keeps_its_approach_speed():
    """A contact still on PUSH_TIME after its impact is written and continued as a push (§15): the same touch, so
    the law keeps its delta_dot0 (a first version took the normal velocity there, about 0 and floored at v_min:
    the damping term jumped ten thousand times). A re-touch within the push takes its own."""
    CT = _arrays()
    PST = CT[5]
    EP.open_episode(PST, 0, 0.0, IMPACT, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    n = EP.episode_step(np.zeros((4, EP.N_IMP)), 0, CT[4], PST, 0, EP.PUSH_TIME + 0.01, 0.0, 0.0, DEPTH, -DEPTH,
                        0.01, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    assert n == 1 and PST[0, C.S_PUSH] == 1.0 and PST[0, C.S_ACT] == EP.IN_CONTACT
    out = _evaluate(_head_on(_x2_at_depth(), 0.5), CT)
    assert out[C.G_FN] == pytest.approx(_law(out[C.G_DEL], out[C.G_DDOT], IMPACT), rel=1e-9)
    # the push's contact ends, and touches again within SEPARATION: its own approach speed
    PST[0, C.S_ACT] = EP.ENDED
    EP.episode_step(np.zeros((4, EP.N_IMP)), 0, CT[4], PST, 0, 1.0, 1.0, 1.0, DEPTH, -DEPTH, 0.2,
                    (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    assert PST[0, C.S_ACT] == EP.IN_CONTACT
    out = _evaluate(_head_on(_x2_at_depth(), 0.1), CT)
    assert out[C.G_FN] == pytest.approx(_law(out[C.G_DEL], out[C.G_DDOT], 0.2), rel=1e-9)


def test_a_retouch_that_opens_the_push_takes_its_own_approach_speed():
    """The impact's contact ended, and the pair touches again later than PUSH_TIME after the impact: the impact
    is written and a push opened at the re-touch, whose approach speed (0.2 m/s) the law takes."""
    CT = _arrays()
    PST = CT[5]
    EP.open_episode(PST, 0, 0.0, IMPACT, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    PST[0, C.S_ACT] = EP.ENDED
    t = EP.PUSH_TIME + 0.05
    n = EP.episode_step(np.zeros((4, EP.N_IMP)), 0, CT[4], PST, 0, t, t, t, DEPTH, -DEPTH, 0.2,
                        (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    assert n == 1 and PST[0, C.S_PUSH] == 1.0 and PST[0, C.S_ACT] == EP.IN_CONTACT
    assert PST[0, C.S_DD0] == PST[0, C.S_DDT] == 0.2
    out = _evaluate(_head_on(_x2_at_depth(), 0.1), CT)
    assert out[C.G_FN] == pytest.approx(_law(out[C.G_DEL], out[C.G_DDOT], 0.2), rel=1e-9)
