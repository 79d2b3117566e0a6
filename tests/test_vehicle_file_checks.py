"""Two silent vehicle-file problems a user found (crashlab 2026-11-27), now refused with one line naming the file
and the key, exit 2 (docs/physics.md §28 "Limits of the input"; crashlab.vehicle):

1. Stiffness in other units read as SI: [structure.front] A = 52.5, B = 689 (meant kN/m, kN/m^2) or A = 300,
   B = 100 (lb/in, lb/in^2) passed, and `crashlab damage` gave EES 1.1 / 3.6 km/h instead of 34 km/h. Bound: the
   full-width residual crush of a 56 km/h rigid-barrier impact, C56 = (15.6 m/s - b0) / b1 with Campbell's crash
   plot b0 = sqrt(2 G w / m), b1 = sqrt(B w / m) (w the side's structure width, m the mass), within 0.05-2 m.
2. Unknown top-level keys were kept silently (the schema keeps model sections such as [multibody]):
   `[structures.front]` fell back to the class default, `cg_to_frnt = 2.9` and `units = "us"` were ignored.

The references are written here (the crash-plot closed forms), not taken from the code under test."""
from __future__ import annotations

import json
import math
import tomllib
from importlib import resources
from pathlib import Path

import pytest
from conftest import assert_one_error_line, assert_refused_with_one_line, damage_cli, write_vehicle_file

from crashlab.scene_file import load_scene
from crashlab.structure import CLASS_REFERENCE, STRUCTURE_SIDES, class_structure
from crashlab.vehicle import library, load_vehicle

MASS, WIDTH, LENGTH = 1600.0, 1.85, 5.0
CAR = f"""name = "user sedan"
class = "mid-size"
mass = {MASS}
yaw_inertia = 2900.0
roll_inertia = 550.0
pitch_inertia = 2800.0
length = {LENGTH}
width = {WIDTH}
height = 1.45
wheelbase = 2.76
track = 1.57
cg_to_front_axle = 1.10
cg_height = 0.55
"""
A_SI, B_SI = 52538.0, 689476.0  # N/m, N/m^2: 300 lb/in, 100 lb/in^2 converted
GOOD = f'[structure.front]\nA = {A_SI}\nB = {B_SI}\nsource = "user"\n'
DAMAGE = ("--side", "front", "--profile", "0.3,0.3,0.3,0.3", "--width", "1.5")


def car(tmp_path, extra: str = GOOD, name: str = "car.toml", head: str = CAR) -> Path:
    return write_vehicle_file(tmp_path, head + extra, name)


cli = damage_cli


def load(path: Path):
    return load_vehicle(path.name, base_dir=path.parent)


def c56_by_hand(A: float, B: float, w: float, m: float) -> float:
    """Campbell's crash plot EBS = b0 + b1 C through the side's no-damage speed: b0 = sqrt(2 G w / m) with
    G = A^2 / 2B, b1 = sqrt(B w / m); the crush at EBS = 56 km/h (15.6 m/s)."""
    b0 = math.sqrt(2.0 * (A * A / (2.0 * B)) * w / m)
    b1 = math.sqrt(B * w / m)
    return (15.6 - b0) / b1


# ------------------------------------------------------------------ 1. stiffness in other units
def test_the_correct_file_passes_and_gives_the_ees_by_hand(tmp_path):
    """The user's file in N/m, N/m^2: EES of a uniform 0.3 m crush over 1.5 m, E = L (A C + B C^2/2 + G) by hand."""
    path = car(tmp_path)
    assert load(path).structure["front"].B == B_SI
    res = cli(path, *DAMAGE, "--json")
    assert res.returncode == 0, res.stderr
    c, L = 0.3, 1.5
    energy = L * (A_SI * c + B_SI * c * c / 2.0 + A_SI * A_SI / (2.0 * B_SI))
    assert json.loads(res.stdout)["ees"] == pytest.approx(math.sqrt(2.0 * energy / MASS), rel=1e-9)  # m/s
    assert math.sqrt(2.0 * energy / MASS) * 3.6 == pytest.approx(34.4, abs=0.05)  # km/h, the user's expectation


@pytest.mark.parametrize("side, A, B, why", [
    ("front", 52.5, 689.0, "kN/m, kN/m^2 read as SI"),
    ("front", 300.0, 100.0, "lb/in, lb/in^2 read as SI"),
    ("rear", 52.5, 689.0, "kN"),
    ("side", 17.5, 345.0, "kN"),
])
def test_stiffness_in_other_units_is_refused_naming_B(tmp_path, side, A, B, why):
    w = LENGTH if side == "side" else WIDTH
    c56 = c56_by_hand(A, B, w, MASS)
    assert c56 > 2.0, (why, c56)  # the case is beyond the bound, by the formula written here
    path = car(tmp_path, f"[structure.{side}]\nA = {A}\nB = {B}\n")
    key = f"structure.{side}.B"
    words = ["C56", "no vehicle structure", "not in N/m^2", f"{c56:.3g} m"]
    assert_refused_with_one_line(load, path, key, words)
    assert_one_error_line(cli(path, "--side", side, "--profile", "0.3,0.3,0.3,0.3", "--width", "1.5"), path, key,
                          words)


def test_a_structure_too_stiff_for_a_light_vehicle_is_refused(tmp_path):
    """The lower end (0.05 m): B at its range's top on a 100 kg, 0.6 m wide vehicle crushes 2 cm at 56 km/h."""
    head = ('name = "scooter"\nmass = 100.0\nyaw_inertia = 32.4\nroll_inertia = 14.1\npitch_inertia = 40.0\n'
            'length = 1.8\nwidth = 0.6\nheight = 1.1\nwheelbase = 1.1\ntrack = 0.5\ncg_to_front_axle = 0.5\n'
            'cg_height = 0.6\n')
    A, B = 4e4, 5e7
    assert c56_by_hand(A, B, 0.6, 100.0) < 0.05
    path = car(tmp_path, f"[structure.front]\nA = {A}\nB = {B}\n", head=head)
    assert_refused_with_one_line(load, path, "structure.front.B", ["C56", "B too large for the mass"])
    assert_one_error_line(cli(path, *DAMAGE), path, "structure.front.B", ["C56"])
    ok = car(tmp_path, "[structure.front]\nA = 4e3\nB = 6e4\n", "ok.toml", head=head)  # C56 0.76 m: passes
    assert 0.3 < c56_by_hand(4e3, 6e4, 0.6, 100.0) < 1.0
    assert load(ok).structure["front"].A == 4e3


def _b_for(c56: float, A: float, w: float, m: float) -> float:
    """B giving the crush c56 at 15.6 m/s with A: b1 solves c56 b1^2 - 15.6 b1 + A w / m = 0 (b0 b1 = A w / m)."""
    b1 = (15.6 + math.sqrt(15.6 ** 2 - 4.0 * c56 * A * w / m)) / (2.0 * c56)
    return b1 * b1 * m / w


@pytest.mark.parametrize("c56, refused", [(1.9, False), (1.99, False), (2.01, True), (2.5, True)])
def test_the_bound_sits_at_2_m(tmp_path, c56, refused):
    A = 5000.0
    B = _b_for(c56, A, WIDTH, MASS)
    assert c56_by_hand(A, B, WIDTH, MASS) == pytest.approx(c56, rel=1e-9)
    path = car(tmp_path, f"[structure.front]\nA = {A}\nB = {B!r}\n")
    res = cli(path, *DAMAGE)
    if refused:
        assert_one_error_line(res, path, "structure.front.B", ["C56"])
    else:
        assert res.returncode == 0, res.stderr


def test_the_bound_by_hand_for_a_library_vehicle():
    """clio.toml's own numbers, read here: C56 by the crash plot; its front estimate was built through 0.50 m at
    15.6 m/s (its source), its rear through 0.40 m at 9.9 m/s, so (15.6 - 2.2) / ((9.9 - 2.2) / 0.40) = 0.696 m."""
    from crashlab.vehicle import crush_56
    data = tomllib.loads(resources.files("crashlab").joinpath("vehicles", "clio.toml").read_text())
    m, width, length = data["mass"], data["width"], data["length"]
    for side, expected in (("front", 0.50), ("rear", (15.6 - 2.2) / ((9.9 - 2.2) / 0.40))):
        s = data["structure"][side]
        w = s.get("width", width)
        by_hand = c56_by_hand(s["A"], s["B"], w, m)
        assert by_hand == pytest.approx(expected, abs=0.002), side
        assert crush_56(s["A"], s["B"], w, m) == pytest.approx(by_hand, rel=1e-12)
    s = data["structure"]["side"]
    assert 0.05 < c56_by_hand(s["A"], s["B"], s.get("width", length), m) < 2.0


def test_every_library_vehicle_and_class_default_passes_with_margin():
    """All sides of every library vehicle lie within 0.2-0.8 m (the bound: 0.05-2 m); so does every class default
    at its class's mass, over its class's width (front, rear) and over the extent of each library vehicle of the
    class (a side's width is the vehicle's length)."""
    values, defaults = [], []
    for ref in library():
        v = load_vehicle(ref)
        cls = tomllib.loads(resources.files("crashlab").joinpath("vehicles", ref + ".toml").read_text())["class"]
        mass = CLASS_REFERENCE[cls][0]
        for side, s in v.structure.items():
            values.append(c56_by_hand(s.A, s.B, s.width, v.mass))
            a, b, _ = class_structure(cls)[side]
            defaults.append(c56_by_hand(a, b, v.length if side == "side" else v.width, mass))
    for cls, (mass, width) in CLASS_REFERENCE.items():
        for side in ("front", "rear"):
            a, b, _ = class_structure(cls)[side]
            defaults.append(c56_by_hand(a, b, width, mass))
    assert len(values) == len(library()) * len(STRUCTURE_SIDES)
    for got in (values, defaults):
        assert 0.2 <= min(got) and max(got) <= 0.8, (min(got), max(got))


SCENE = ('name = "s"\nduration = 1.0\n[road]\nfriction = 0.8\n[[vehicles]]\nname = "V1"\nvehicle = "{vehicle}"\n'
         'x = 0.0\ny = 0.0\nheading = 0.0\nspeed = 30.0\n')


@pytest.mark.parametrize("override, key, word", [
    ("[vehicles.overrides.structure.front]\nA = 52.5\nB = 689.0\n", "structure.front.B", "C56"),
    ("[vehicles.overrides.structure.side]\nA = 17.5\nB = 345.0\n", "structure.side.B", "C56"),
    # B alone in kN/m^2 under the file's A: the no-damage speed's bound (68 m/s) comes first
    ("[vehicles.overrides.structure.front]\nB = 689.0\n", "structure.front.B", "no-damage speed"),
    # the file's structure on 30 t (inertias scaled with it): C56 2.3 m, named by the overridden mass
    ("[vehicles.overrides]\nmass = 30000.0\nyaw_inertia = 767000.0\nroll_inertia = 14900.0\n"
     "pitch_inertia = 73200.0\n", "mass", "C56"),
])
def test_a_scene_override_of_the_stiffness_goes_through_the_same_check(tmp_path, override, key, word):
    car(tmp_path)
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE.format(vehicle="car.toml") + override)
    full = f"vehicles.V1.overrides.{key}"
    assert_refused_with_one_line(load_scene, scene, full, [word, "no vehicle structure"])
    assert_one_error_line(cli(scene.name, *DAMAGE, cwd=tmp_path), scene.name, full, [word])


def test_an_override_of_a_only_moves_c56_little_and_passes(tmp_path):
    """A only sets b0 (0.3 to 8 m/s): A = 15,000 N/m under the file's B gives b0 0.61 m/s and C56 0.53 m, a
    plausible structure (A = 300 N/m, b0 0.012 m/s, passed until 2026-11-27: A in kN/m or lbf/in is refused now,
    tests/test_damage_fuzz.py)."""
    car(tmp_path)
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE.format(vehicle="car.toml") + "[vehicles.overrides.structure.front]\nA = 15000.0\n")
    assert 0.5 < c56_by_hand(15000.0, B_SI, WIDTH, MASS) < 0.6
    assert load_scene(scene).vehicles[0].spec.structure["front"].A == 15000.0


def test_a_scene_in_us_units_overriding_the_stiffness_passes(tmp_path):
    """300 lb/in = 3600 lbf/ft and 100 lb/in^2 = 14400 lbf/ft^2 in a US scene are the SI file's numbers."""
    car(tmp_path, "")
    scene = tmp_path / "scene.toml"
    scene.write_text('units = "us"\n' + SCENE.format(vehicle="car.toml")
                     + "[vehicles.overrides.structure.front]\nA = 3600.0\nB = 14400.0\n")
    s = load_scene(scene).vehicles[0].spec.structure["front"]
    assert s.A == pytest.approx(A_SI, rel=1e-3) and s.B == pytest.approx(B_SI, rel=1e-3)


# ------------------------------------------------------------------ 2. unknown top-level keys
@pytest.mark.parametrize("extra, key, words", [
    (GOOD.replace("[structure.front]", "[structures.front]"), "structures",
     ["unknown key", "did you mean 'structure'?"]),
    ("[Structure.front]\nA = 52538.0\nB = 689476.0\n", "Structure", ["unknown key", "did you mean 'structure'?"]),
    ("[multibdy.chassis]\nmass = 1200.0\n", "multibdy", ["unknown key", "did you mean 'multibody'?"]),
    ("cg_to_frnt = 2.9\n" + GOOD, "cg_to_frnt", ["unknown key", "did you mean 'cg_to_front'?"]),
    ('units = "us"\n' + GOOD, "units", ["unknown key", "SI units"]),
    ('colour = "red"\n' + GOOD, "colour", ["unknown key"]),
    ("tags = []\n" + GOOD, "tags", ["unknown key"]),
])
def test_an_unknown_key_is_refused_naming_it(tmp_path, extra, key, words):
    path = car(tmp_path, extra)
    assert_refused_with_one_line(load, path, key, words)
    assert_one_error_line(cli(path, *DAMAGE), path, key, words)


def test_an_unknown_value_is_named_before_the_schema_complains(tmp_path):
    """`mas = 1600` (mass missing): the typo is named, not the missing mass."""
    path = car(tmp_path, head=CAR.replace("mass =", "mas ="))
    assert_refused_with_one_line(load, path, "mas", ["unknown key", "did you mean 'mass'?"])


def test_a_model_section_of_its_own_name_stays_allowed(tmp_path):
    """Tables a third-party model reads: kept as written in the spec's sections, also names that merely resemble
    a key (wheels, chassis, body, inertia) and an array of tables."""
    extra = GOOD + ("[mymodel]\nk = 1.0\n[wheels]\nn = 4\n[chassis]\nstiff = 2.0\n[body]\nshape = \"box\"\n"
                    "[inertia]\nx = 1.0\n[[mymodel_parts]]\nm = 2.0\n[[mymodel_parts]]\nm = 3.0\n")
    path = car(tmp_path, extra)
    spec = load(path)
    assert spec.sections["mymodel"] == {"k": 1.0} and spec.sections["wheels"] == {"n": 4}
    assert spec.sections["mymodel_parts"] == [{"m": 2.0}, {"m": 3.0}]
    assert {"chassis", "body", "inertia"} <= set(spec.sections)
    assert cli(path, *DAMAGE).returncode == 0


@pytest.mark.parametrize("override, key, words", [
    ("[vehicles.overrides.structures.front]\nA = 52538.0\nB = 689476.0\n", "structures",
     ["unknown vehicle key", "did you mean 'structure'?"]),
    ("[vehicles.overrides]\ncg_to_frnt = 2.9\n", "cg_to_frnt", ["unknown vehicle key", "did you mean 'cg_to_front'?"]),
    ("[vehicles.overrides]\nmas = 1500.0\n", "mas", ["unknown vehicle key", "did you mean 'mass'?"]),
    ("[vehicles.overrides.othermodel]\nk = 2.0\n", "othermodel", ["unknown vehicle key"]),  # not in the file
])
def test_an_unknown_override_is_refused_as_before_with_the_hint(tmp_path, override, key, words):
    car(tmp_path)
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE.format(vehicle="car.toml") + override)
    full = f"vehicles.V1.overrides.{key}"
    assert_refused_with_one_line(load_scene, scene, full, words)
    assert_one_error_line(cli(scene.name, *DAMAGE, cwd=tmp_path), scene.name, full, words)


def test_an_override_of_the_file_s_own_model_section_passes(tmp_path):
    car(tmp_path, GOOD + "[mymodel]\nk = 1.0\n")
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE.format(vehicle="car.toml") + "[vehicles.overrides.mymodel]\nk = 2.0\n")
    assert load_scene(scene).vehicles[0].spec.sections["mymodel"] == {"k": 2.0}


def test_every_library_vehicle_loads_and_has_only_known_or_model_keys():
    from crashlab.vehicle import unknown_key_problem
    for ref in library():
        data = tomllib.loads(resources.files("crashlab").joinpath("vehicles", ref + ".toml").read_text())
        assert unknown_key_problem(data) is None, ref
        load_vehicle(ref)


def test_a_byte_order_mark_is_named(tmp_path):
    """A UTF-8 BOM gave "malformed TOML: Invalid statement (at line 1, column 1)" without saying why (a fuzzer,
    2026-11-27)."""
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + b'name = "s"\nduration = 1.0\n')
    assert_refused_with_one_line(load_scene, path, "(syntax)", ["byte-order mark", "without BOM"])


def test_a_structure_width_just_beyond_the_vehicle_shows_the_difference(tmp_path):
    """1.6400001 m on a 1.64 m car read "(1.64 m) must not exceed the vehicle's width (1.64 m)" (a fuzzer)."""
    text = (resources.files("crashlab.vehicles") / "clio.toml").read_text()
    width = tomllib.loads(text)["width"]
    path = write_vehicle_file(tmp_path, text.replace("[structure.front]\n", f"[structure.front]\nwidth = "
                                                                            f"{width + 1e-7!r}\n"))
    assert_refused_with_one_line(lambda p: load_vehicle(p.name, base_dir=p.parent), path, "structure.front.width",
                                 [f"({width + 1e-7!r} m)", f"({width!r} m)"])
