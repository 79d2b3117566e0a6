"""Scene inputs accepted without effect (found by a fuzzer from outside, 2026-11-27): a vehicle named "V1 " beside
"V1" (two names that read alike in every table) or " "; [impact] engagement_depth without point = "engagement",
which no model reads then (the run was the same as without it), also as a study's or Monte Carlo's field. Each is
now one line naming the file and key."""
import sys
from pathlib import Path

import pytest

import crashlab
from crashlab import fields
from crashlab.scene_file import scene_from_dict

sys.path.insert(0, str(Path(__file__).parent))
from conftest import build_scene  # noqa: E402


def _scene(names=("V1", "V2"), impact=None):
    data = {"name": "s", "duration": 1.0,
            "vehicles": [{"name": n, "vehicle": "clio", "x": 6.0 * k} for k, n in enumerate(names)]}
    if impact is not None:
        data["impact"] = impact
    return scene_from_dict(data, source="s.toml")


@pytest.mark.parametrize("name", ["V1 ", " ", " V2"])
def test_a_name_with_spaces_at_its_ends_is_refused(name):
    with pytest.raises(crashlab.InputError) as err:
        _scene(("V1", name))
    assert str(err.value) == f"s.toml: vehicles.1.name: no spaces at the start or end, got {name!r}"


def test_a_name_with_a_space_inside_is_a_name():
    assert list(_scene(("Car A", "Car B")).vehicle_names) == ["Car A", "Car B"]


def test_engagement_depth_without_the_engagement_point_is_refused():
    with pytest.raises(crashlab.InputError) as err:
        _scene(impact={"engagement_depth": 0.3})
    assert str(err.value).startswith('s.toml: impact.engagement_depth: acts only with point = "engagement"')
    assert _scene(impact={"point": "engagement", "engagement_depth": 0.3}).impact.engagement_depth == 0.3


def test_engagement_depth_as_a_field_needs_the_engagement_point():
    plain = build_scene([{}, {"x": 6.0}])
    with pytest.raises(ValueError, match='acts only with .impact. point = "engagement"'):
        fields.resolve(plain, "impact.engagement_depth")
    engaged = build_scene([{}, {"x": 6.0}], impact={"point": "engagement"})
    assert fields.get(engaged, "impact.engagement_depth") == 0.5


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero")
def test_a_device_that_never_ends_is_refused_not_read_forever():
    """`crashlab simulate /dev/zero` read until the process was killed; a TOML input is read up to 64 MB."""
    from crashlab.input_files import TOML_BYTES_MAX, read_toml
    with pytest.raises(crashlab.InputError) as err:
        read_toml(Path("/dev/zero"), "scene")
    assert str(err.value) == (f"/dev/zero: scene: larger than {TOML_BYTES_MAX >> 20} MB: not a scene, study or "
                              "vehicle file")
