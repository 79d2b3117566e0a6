"""Benchmark (issue 4): 5 s of the Clio braking with locked wheels from 50 km/h. Goal <= 0.2 s wall."""
from crashlab.models.multibody import MultibodyModel
from crashlab.scene_file import scene_from_dict


def test_bench_multibody_clio_braking_50(benchmark):
    sc = scene_from_dict({"duration": 5.0, "road": {"friction": 0.8}, "vehicles": [
        {"name": "V1", "vehicle": "clio", "speed": 50.0, "wheels": "locked"}]})
    model = MultibodyModel()
    model.simulate(sc)                      # compile (numba cache) and settle the vehicle once
    out = benchmark(model.simulate, sc)
    assert out.outcome_ok
    assert abs(out.rest_si[0, 0] / 12.29 - 1.0) < 0.02


def test_bench_multibody_side_collision_with_30_parked(benchmark):
    """The scaling study's scene: the side collision and 30 parked Clios (they start asleep; the step's pair
    bookkeeping and the road contact skip them since 2026-11-27: 0.35 -> 0.19 s CPU, the two cars alone 0.12 s)."""
    from crashlab.comparison.scaling import scene
    sc = scene(32, "parked")
    model = MultibodyModel()
    model.simulate(sc)                      # compile (numba cache)
    out = benchmark(model.simulate, sc)
    assert out.outcome_ok
