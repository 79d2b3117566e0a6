"""The scaling study (crashlab.comparison.scaling) on a tiny configuration: impulse, 2 and 8 vehicles.

The CSV contract (exact columns), the scenes (no start overlap, the others far from the crash), and one
physical fact on a work measure, never on wall time: a parked vehicle costs less than a moving one. Parked
vehicles sleep from the start, so they add no integration steps and the run ends with the colliding pair's
rest; driving ones keep the run going to its duration; with sleeping off, parked ones cost steps too.
"""
import math

import pandas as pd
import pytest

from crashlab.comparison import scaling


@pytest.fixture(scope="module")
def rows():
    return scaling.model_rows("impulse", quick=True, sizes=(2, 8),
                              variant_names={"parked", "driving", "parked/no-sleep", "parked/no-broad-phase"},
                              repeats=1)


def test_csv_contract(rows, tmp_path):
    df = scaling.rows_frame(rows)
    path = tmp_path / "scaling.csv"
    df.to_csv(path, index=False)
    back = pd.read_csv(path)
    assert list(back.columns) == ["model", "n_vehicles", "variant", "wall_time_s", "t_end_s",
                                  "wall_per_sim_second", "ok", "steps", "note"]
    assert list(back.columns[:4]) == ["model", "n_vehicles", "variant", "wall_time_s"]
    assert set(back["n_vehicles"]) == {2, 8}
    assert set(back["variant"]) == {"parked", "driving", "parked/no-sleep", "parked/no-broad-phase"}
    assert back["ok"].astype(str).eq("True").all()
    assert (back["wall_time_s"] > 0).all()
    ratio = scaling.ratios(df)
    assert list(ratio.columns) == scaling.RATIO_COLUMNS
    assert set(ratio["n_large"]) == {8}


def test_scenes_are_far_apart():
    from crashlab.scene import start_overlaps
    for base in ("parked", "driving"):
        s = scaling.scene(32, base)
        assert len(s.vehicles) == 32 and not start_overlaps(s)
        others = s.vehicles[2:]
        assert min(v.y for v in others) >= 25.0  # beside the crash, out of every broad phase's reach
        assert all(v.speed == (0.0 if base == "parked" else pytest.approx(50 / 3.6)) for v in others)


def test_parked_vehicle_costs_less_than_a_moving_one(rows):
    cell = {(r["variant"], r["n_vehicles"]): r for r in rows}
    two, parked, driving = cell["parked", 2], cell["parked", 8], cell["driving", 8]
    # six parked vehicles add no integration step: the run is the colliding pair's, step for step
    assert parked["steps"] == two["steps"]
    assert parked["t_end_s"] == pytest.approx(two["t_end_s"]) and parked["t_end_s"] < scaling.DURATION
    # six driving ones keep the run going to its duration, with more steps
    assert driving["t_end_s"] == pytest.approx(scaling.DURATION)
    assert driving["steps"] > parked["steps"]
    # sleeping is what makes parking cheap: switched off, the parked vehicles cost steps as well
    assert cell["parked/no-sleep", 8]["steps"] > parked["steps"]
    # the broad phase changes the work per step, not the result: same steps, same end
    nb = cell["parked/no-broad-phase", 8]
    assert nb["steps"] == parked["steps"] and math.isclose(nb["t_end_s"], parked["t_end_s"])


def test_switches_and_na():
    assert scaling.switches("impulse") == {"sleeping": ({"sleeping": False}, ""),
                                           "broad_phase": ({"broad_phase": False}, "")}
    assert scaling.switches("multibody")["sleeping"][0] == {"t_sleep": 1e9}
    assert scaling.switches("pymunk")["broad_phase"][0] is None
    na = [v for v in scaling.variants("exudyn") if v[2] is None]
    assert {v[0] for v in na} == {"parked/no-sleep", "parked/no-broad-phase", "driving/no-sleep",
                                  "driving/no-broad-phase"}
    assert all(v[3] for v in na)  # each with its reason
