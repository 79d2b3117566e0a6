"""Populations (crashlab.population, CollisionModel.simulate_population): many variants of one scene as arrays.

* the impulse model writes the variants' values into its kernel's arrays: the arrays are, bit for bit, the
  ones it packs of each changed scene (every kind of field it writes directly), so its population equals what
  simulate_batch gives on those scenes (rest poses, impact columns; the issue asks 1e-9 m, they are equal);
* the base class (any plugin) builds a scene per row over simulate_batch and gets the same;
* the physics guard runs on the arrays with its own start energy (1/2 m v^2 + 1/2 Iz r^2 written here);
* bad input: an unknown field, a value out of range or NaN names the field and the row.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import crashlab
from crashlab import fields
from crashlab.model import CollisionModel
from crashlab.models.impulse import ImpulseModel
from crashlab.models.impulse import population as impulse_population
from crashlab.population import Population, Variants
from crashlab.reconstruction.evidence import EvidenceItem, EvidenceSet

REPO = Path(__file__).resolve().parent.parent
SIDE = REPO / "studies" / "pc_crash" / "side.toml"
ZONES = REPO / "studies" / "driver" / "side_actions_zones.toml"
SPEEDS_HEADINGS = ["vehicles.V1.speed", "vehicles.V1.heading", "vehicles.V2.speed", "vehicles.V2.heading"]


@pytest.fixture(scope="module")
def model():
    return ImpulseModel()


def _rows(n, seed=1):
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(40, 60, n), rng.uniform(-10, 10, n), rng.uniform(20, 40, n),
                            rng.uniform(80, 100, n)])


def _masses(scenes):
    return np.array([[v.spec.mass for v in s.vehicles] for s in scenes])


DIRECT = [  # every kind of field the impulse model writes into its arrays, with values in range
    ("vehicles.V1.x", (-1.0, 0.5)), ("vehicles.V2.y", (-0.5, 0.3)), ("vehicles.V1.heading", (-7.0, 3.0)),
    ("vehicles.V2.speed", (25.0, 35.0)), ("vehicles.V1.yaw_rate", (-20.0, 10.0)),
    ("vehicles.V1.mass", (1000.0, 1200.0)), ("vehicles.V2.yaw_inertia", (1500.0, 1700.0)),
    ("road.friction", (0.6, 0.9)), ("road.zones.1.friction", (0.3, 0.6)),
    ("impact.restitution", (0.05, 0.2)), ("impact.friction", (0.2, 0.5)),
]


@pytest.mark.parametrize("path,span", DIRECT, ids=[p for p, _ in DIRECT])
def test_direct_writes_are_the_packed_arrays_of_the_changed_scene_bit_for_bit(model, path, span):
    scene = crashlab.load_scene(ZONES)
    fs = [fields.resolve(scene, path)]
    values = np.linspace(*span, 7)[:, None]
    assert all(impulse_population._direct(f) for f in fs)
    got = impulse_population.pack_variants(model, scene, fs, values)
    build = fields.setter(scene, fs)
    packs = [model.pack(build(row)) for row in values]
    want = [np.stack([p[k] for p in packs]) for k in range(6)] + [np.stack([p[6][k] for p in packs]) for k in range(4)]
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)
    changed = [k for k, w in enumerate(want) if not np.all(w == w[:1])]
    assert changed, "the field changes some array (the test compares something)"


def _equal_to_batch(model, scene, paths, values):
    pop = model.simulate_population(scene, paths, values)
    build = fields.setter(scene, paths)
    scenes = [build(row) for row in values]
    ref = Population.of_outcomes(model.simulate_batch(scenes), scene.vehicle_names, _masses(scenes))
    assert pop.ok.all() and ref.ok.all(), (pop.reason, ref.reason)
    np.testing.assert_array_equal(pop.rest, ref.rest)  # (the issue asks 1e-9 m)
    np.testing.assert_array_equal(pop.final, ref.final)
    np.testing.assert_array_equal(pop.n_impacts, ref.n_impacts)
    np.testing.assert_array_equal(pop.at_rest, ref.at_rest)
    for name in ("delta_v", "first_delta_v", "crush_energy", "first_impact_t", "first_impact_point",
                 "energy_start", "energy_end", "energy_impacts", "lowest_impact_energy", "contact"):
        np.testing.assert_allclose(getattr(pop, name), getattr(ref, name), rtol=1e-12, atol=1e-9, err_msg=name)
    return pop


def test_impulse_population_equals_simulate_batch_on_speeds_and_headings(model):
    pop = _equal_to_batch(model, crashlab.load_scene(SIDE), SPEEDS_HEADINGS, _rows(40))
    assert np.ptp(pop.rest[:, 0, 0]) > 0.5, "the variants differ"
    # delta-V from momentum: m1 dv1 = m2 dv2 in a two-car impact (the impulse on each is the same)
    np.testing.assert_allclose(pop.delta_v[:, 0] * pop.mass[:, 0], pop.delta_v[:, 1] * pop.mass[:, 1], rtol=1e-9)


def test_impulse_population_of_actions_packs_each_variant_and_equals_simulate_batch(model):
    scene = crashlab.load_scene(ZONES)
    paths = ["vehicles.V1.actions.0.t", "vehicles.V1.speed"]
    lo, hi = fields.field_range(scene, paths[0])
    values = np.column_stack([np.linspace(lo, min(hi, lo + 0.3), 6), np.linspace(45, 55, 6)])
    assert not impulse_population._direct(fields.resolve(scene, paths[0]))
    _equal_to_batch(model, scene, paths, values)


class Planar(CollisionModel):
    """A plugin without a population of its own: the base class's route over simulate_batch. Each car stops
    where it is after 1 s at its start speed along its heading (no impact rows)."""
    name = "planar-test"

    def simulate(self, scene):
        rest = [(v.x + v.speed * np.cos(v.heading), v.y + v.speed * np.sin(v.heading), v.heading)
                for v in scene.vehicles]
        return crashlab.Outcome(scene.vehicle_names, rest, np.zeros((len(rest), 3)), model=self.name)


class Creating(Planar):
    """A plugin whose own population claims every car still moves at twice its start speed at the end."""
    name = "creating-test"

    def simulate_population(self, scene, fs, values):
        pop = Population.empty(len(values), scene.vehicle_names, "")
        pop.ok[:] = True
        pop.rest[:] = 0.0
        speed = fields.vehicle_columns(scene, fs, values, ("speed",))["speed"]
        pop.final[:] = 0.0
        pop.final[..., 0] = 2.0 * speed
        return pop


def test_base_class_population_is_the_batch_of_scenes():
    scene = crashlab.load_scene(SIDE)
    values = _rows(5)
    pop = Planar().simulate_population(scene, SPEEDS_HEADINGS, values)
    h = np.radians(values[:, 1])
    np.testing.assert_allclose(pop.rest[:, 0, 0], scene.vehicles[0].x + values[:, 0] / 3.6 * np.cos(h), atol=1e-12)
    assert pop.ok.all() and (pop.n_impacts == 0).all() and pop.at_rest.all()


def test_the_guard_fails_rows_that_create_energy_from_its_own_start_energy():
    scene = crashlab.load_scene(SIDE)
    values = _rows(4)
    pop = Creating().simulate_population(scene, SPEEDS_HEADINGS, values)
    m = np.array([v.spec.mass for v in scene.vehicles])
    iz = np.array([v.spec.yaw_inertia for v in scene.vehicles])
    r = np.array([v.yaw_rate for v in scene.vehicles])
    v = values[:, [0, 2]] / 3.6
    e0 = (0.5 * m * v ** 2 + 0.5 * iz * r ** 2).sum(1)  # written here, not the guard's function
    np.testing.assert_allclose(pop.energy_start, e0, rtol=1e-12)
    np.testing.assert_allclose(pop.energy_end, (0.5 * m * (2 * v) ** 2).sum(1), rtol=1e-12)
    assert not pop.ok.any()
    assert all(r.startswith("physics guard: energy_overall: kinetic energy") for r in pop.reason)


def test_the_guard_fails_an_impulse_row_whose_impact_creates_energy(model, monkeypatch):
    scene = crashlab.load_scene(SIDE)
    real = impulse_population.population_of

    def lying(*args):
        pop = real(*args)
        pop.lowest_impact_energy[1] = -50e3  # as a kernel that made an impact create 50 kJ would report
        return pop
    monkeypatch.setattr(impulse_population, "population_of", lying)
    pop = model.simulate_population(scene, SPEEDS_HEADINGS, _rows(3))
    assert list(pop.ok) == [True, False, True]
    assert pop.reason[1].startswith("physics guard: impact_energy: an impact creates 50.0 kJ")


def test_bad_input_names_the_field_and_the_row(model):
    scene = crashlab.load_scene(SIDE)
    with pytest.raises(ValueError, match=r"field 'vehicles\.V3\.speed': no vehicle 'V3'"):
        model.simulate_population(scene, ["vehicles.V3.speed"], [[50.0]])
    values = _rows(4)
    values[2, 0] = 500.0
    with pytest.raises(ValueError, match=r"^row 2: vehicles\.V1\.speed = 500 is outside \[0, 400\] km/h$"):
        model.simulate_population(scene, SPEEDS_HEADINGS, values)
    values[2, 0], values[3, 3] = 50.0, np.nan
    with pytest.raises(ValueError, match=r"^row 3: vehicles\.V2\.heading = nan is outside"):
        model.simulate_population(scene, SPEEDS_HEADINGS, values)
    pop = model.simulate_population(scene, SPEEDS_HEADINGS, values, invalid="fail")
    assert list(pop.ok) == [True, True, True, False]
    assert pop.reason[3].startswith("no valid scene: vehicles.V2.heading = nan")


def _overlap_by_edges(c1, c2):
    """Two convex quadrilaterals (corners (4, 2)) overlap: an edge of one crosses an edge of the other, or a corner
    of one lies inside the other (written here: orientation signs, not the code's separating axes)."""
    def orient(a, b, c):
        return np.sign((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))

    def inside(p, poly):
        signs = {orient(poly[k], poly[(k + 1) % 4], p) for k in range(4)}
        return signs <= {1.0} or signs <= {-1.0}
    for i in range(4):
        for j in range(4):
            a, b, c, d = c1[i], c1[(i + 1) % 4], c2[j], c2[(j + 1) % 4]
            if orient(a, b, c) * orient(a, b, d) < 0 and orient(c, d, a) * orient(c, d, b) < 0:
                return True
    return inside(c1[0], c2) or inside(c2[0], c1)


def test_start_overlap_of_whole_columns_is_the_outlines_crossing():
    rng = np.random.default_rng(4)
    n = 400
    x1, y1, h1, x2, y2, h2 = (rng.uniform(-4.0, 4.0, n) for _ in range(6))
    hit = crashlab.geometry.rect_overlap_rows((x1, y1, h1, 2.0, 2.4, 0.9), (x2, y2, h2, 1.6, 1.1, 0.8)) > 0
    want = np.array([_overlap_by_edges(crashlab.geometry.rect_corners(x1[k], y1[k], h1[k], 2.0, 2.4, 0.9),
                                       crashlab.geometry.rect_corners(x2[k], y2[k], h2[k], 1.6, 1.1, 0.8))
                     for k in range(n)])
    assert 0.2 < want.mean() < 0.8 and (hit == want).all()


def test_a_row_that_puts_two_cars_on_top_of_each_other_is_no_valid_scene(model):
    """The scene file refuses vehicles overlapping at the start; a population's row did not: V1 moved onto V2
    ran through it with "no contact", or gave an impact of 34 km/h with no warning (found by a fuzzer)."""
    scene = crashlab.load_scene(SIDE)
    v2 = scene.vehicle("V2")
    values = np.array([[scene.vehicle("V1").x], [v2.x]])
    with pytest.raises(ValueError, match=r"^row 1: vehicles\.V1\.x = 3\.5: V1 and V2 overlap at the start$"):
        model.simulate_population(scene, ["vehicles.V1.x"], values)
    for m in (model, Planar()):  # the impulse model's own population and the base class's
        pop = m.simulate_population(scene, ["vehicles.V1.x"], values, invalid="fail")
        assert list(pop.ok) == [True, False]
        assert pop.reason[1] == "no valid scene: vehicles.V1.x = 3.5: V1 and V2 overlap at the start"
    with pytest.raises(ValueError, match="V1 and V2 overlap at the start"):
        fields.set_fields(scene, ["vehicles.V2.x", "vehicles.V2.y"], [1.19396457, -1.02636848])
    # a scene at its collision position ([impact] point) starts in contact: its rows are not refused for it
    at_point = crashlab.load_scene(REPO / "studies" / "validation" / "rose4363_accord_blazer.toml")
    pop = model.simulate_population(at_point, ["vehicles.V1.x"], [[0.0], [0.05]])
    assert pop.ok.all()


def test_values_must_have_a_column_per_field_and_each_field_once(model):
    scene = crashlab.load_scene(SIDE)
    with pytest.raises(ValueError, match=r"values of shape \(3, 2\): \(N, 1\) for 1 field"):
        model.simulate_population(scene, ["vehicles.V1.speed"], [[40.0, 5.0], [50.0, 6.0], [60.0, 7.0]])
    pop = model.simulate_population(scene, ["vehicles.V1.speed"], [40.0, 50.0, 60.0])  # one field: N values
    assert len(pop.ok) == 3 and pop.ok.all()
    assert len(model.simulate_population(scene, [], np.zeros((3, 0))).ok) == 3
    for m in (model, Planar()):
        with pytest.raises(ValueError, match=r"field 'vehicles\.V1\.speed' given twice"):
            m.simulate_population(scene, ["vehicles.V1.speed", "vehicles.V1.speed"], [[30.0, 60.0]])


def test_pymunk_fails_a_row_with_a_mass_chipmunk_cannot_take():
    """Unchecked rows are the caller's to keep in range, but a negative mass made Chipmunk abort the whole
    process; now the row fails with the reason."""
    pytest.importorskip("pymunk")
    scene = crashlab.load_scene(SIDE)
    pop = crashlab.get_model("pymunk").simulate_population(scene, ["vehicles.V1.mass"], [[1200.0], [-500.0]],
                                                           invalid="unchecked")
    assert list(pop.ok) == [True, False]
    assert "V1: mass -500 kg and yaw inertia" in pop.reason[1]


def test_outcome_of_a_variant_and_the_frame(model):
    scene = crashlab.load_scene(SIDE)
    values = _rows(3)
    pop = model.simulate_population(scene, SPEEDS_HEADINGS, values)
    out = pop.outcome(1)
    np.testing.assert_array_equal(out.rest_si, pop.rest[1])
    assert out.trajectories and out.impact_rows
    frame = pop.to_frame()
    assert list(frame["vehicles.V1.speed"]) == list(values[:, 0])
    np.testing.assert_allclose(frame["V2.delta_v"], pop.delta_v[:, 1] * 3.6)


def test_evidence_scored_on_the_arrays_equals_the_outcomes_scores(model):
    scene = crashlab.load_scene(SIDE)
    es = EvidenceSet(scene.vehicle_names, [
        EvidenceItem("rest", "rest.V1", ("V1",), ("x", "y", "heading"), (4.0, 0.5, 50.0), (0.2, 0.2, 5.0)),
        EvidenceItem("impact", "impact", ("V1", "V2"), ("x", "y"), (1.5, 0.2), (0.3, 0.3)),
        EvidenceItem("edr", "edr.V2", ("V2",), ("speed_at_impact", "delta_v"), (30.0, 25.0), (2.0, 3.0)),
        EvidenceItem("damage", "damage.V2", ("V2",), ("ees",), (20.0,), (4.0,), mass=1100.0, side="left")])
    values = _rows(6)
    pop = model.simulate_population(scene, SPEEDS_HEADINGS, values)
    build = fields.setter(scene, SPEEDS_HEADINGS)
    outs = [model.simulate(build(row)) for row in values]
    np.testing.assert_allclose(es.population_residuals(pop), es.residuals(outs), rtol=1e-10, atol=1e-10)
    assert np.isfinite(es.population_residuals(pop)).all()


@pytest.mark.slow  # worker processes load the numba cache
@pytest.mark.parametrize("backend", ["processes", "dask"])
def test_the_executor_sends_the_scene_and_blocks_of_rows_to_its_workers(model, backend):
    """Worker processes and a local Dask cluster (2 workers) get the scene and blocks of rows (Variants) and
    return what this process computes, bit for bit, in the rows' order; one bad row (NaN speed, invalid="fail")
    fails only itself there too."""
    if backend == "dask":
        pytest.importorskip("dask.distributed")
    scene = crashlab.load_scene(SIDE)
    values = _rows(20)
    values[7, 0] = np.nan
    here = model.simulate_population(scene, SPEEDS_HEADINGS, values, invalid="fail")
    with crashlab.execution.Executor(backend, workers=2) as ex:
        there = ex.evaluate("impulse", {}, Variants(scene, tuple(SPEEDS_HEADINGS), values, invalid="fail"))
    assert isinstance(there, Population) and len(there.ok) == 20
    assert not there.ok[7] and "vehicles.V1.speed" in there.reason[7] and there.ok[np.arange(20) != 7].all()
    np.testing.assert_array_equal(there.rest, here.rest)
    np.testing.assert_array_equal(there.ok, here.ok)
    np.testing.assert_array_equal(there.delta_v, here.delta_v)


@pytest.mark.parametrize("model_name", ["impulse", "pymunk"])  # its own population; the base class's route
def test_the_population_masses_are_the_rows_masses_also_of_a_row_that_fails(model_name):
    """pop.mass [kg] is each variant's mass: the row's value where the mass is a field, the scene's vehicle
    mass where not, also for a row that is no valid scene (20 kg, below crashlab.vehicle.MASS_RANGE)."""
    from crashlab.registry import get_model
    scene = crashlab.load_scene(SIDE)
    values = np.array([[1100.0, 50.0], [20.0, 50.0], [1500.0, 45.0]])
    pop = get_model(model_name).simulate_population(scene, ["vehicles.V1.mass", "vehicles.V2.speed"], values,
                                                    invalid="fail")
    assert list(pop.ok) == [True, False, True]
    want = np.column_stack([values[:, 0], np.full(3, scene.vehicles[1].spec.mass)])
    np.testing.assert_array_equal(pop.mass, want)


def test_a_run_whose_impact_rows_name_no_struck_side_fails_with_the_reason():
    """Its energy cannot be booked to the side damage evidence compares (docs/physics.md §28): the run fails in the
    population, naming the vehicles (rows naming no side, and rows naming "side", which does not say the flank);
    the same rows with their faces pass and book the energy there."""
    from crashlab.outcome import Outcome
    row = {"t": 0.1, "vehicle": "V1", "other": "V2", "dvx": -1.0, "dvy": 0.0, "d_yaw_rate": 0.0, "energy": 1e3,
           "crush_energy": 400.0, "kind": "full", "point_x": 0.0, "point_y": 0.0, "plane_angle": 0.0}
    rows = [row, {**row, "vehicle": "V2", "other": "V1", "crush_energy": 600.0}]
    flank = [{**rows[0], "side": "front"}, {**rows[1], "side": "side"}]
    named = [{**rows[0], "side": "front"}, {**rows[1], "side": "right"}]
    pop = Population.of_outcomes([Outcome(["V1", "V2"], np.zeros((2, 3)), np.zeros((2, 3)), impact_rows=r)
                                  for r in (rows, flank, named)], ["V1", "V2"])
    assert list(pop.ok) == [False, False, True]
    assert pop.reason[0].startswith("the model's impact rows of V1, V2 name no struck face")
    assert pop.reason[1].startswith("the model's impact rows of V2 name no struck face")
    # front, rear, left, right, roof, underbody (crashlab.structure.IMPACT_FACES)
    np.testing.assert_array_equal(pop.crush_energy[2], [[400.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                                                        [0.0, 0.0, 0.0, 600.0, 0.0, 0.0]])
