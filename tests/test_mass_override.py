"""Vehicle overrides of mass and inertias are honoured by every model (issue 10): the Clio overridden to
700 kg against the SUV gives the delta-V split that momentum conservation demands, m1 dv1 = m2 dv2, in all
four models (10 % slack for the continuous-contact models, whose delta-V is the CG velocity change over a
contact episode while the road also acts: crashlab.testing)."""
from __future__ import annotations

import pytest
from conftest import build_scene

import crashlab
from crashlab.vehicle import load_vehicle

MODELS = ["impulse", "pymunk", "multibody", "exudyn"]


def _scene():
    clio, suv = load_vehicle("clio"), load_vehicle("suv")
    k = 700.0 / clio.mass
    light = {"mass": 700.0, "yaw_inertia": clio.yaw_inertia * k, "roll_inertia": clio.roll_inertia * k,
             "pitch_inertia": clio.pitch_inertia * k}
    return build_scene([{"vehicle": "clio", "x": 0.0, "speed": 50.0, "overrides": light},
                        {"vehicle": "suv", "x": 5.0, "heading": 180.0, "speed": 0.0}], duration=1.0), suv.mass


@pytest.mark.parametrize("model", MODELS)
def test_light_clio_against_suv_delta_v_split(model):
    if model in ("pymunk", "exudyn"):
        pytest.importorskip(model)
    scene, m_suv = _scene()
    out = crashlab.simulate(scene, model=model)
    assert out.outcome_ok, out.warnings
    imp = out.impacts
    first = imp.t.min()
    dv = imp[imp.t == first].set_index("vehicle").delta_v
    ratio = dv["V1"] / dv["V2"]
    assert ratio == pytest.approx(m_suv / 700.0, rel=0.10), (dv.to_dict(), m_suv)
