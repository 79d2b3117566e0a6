"""Seeded random multi-vehicle scenes for the independent guard audit (issue 27; tests/test_guard_audit.py).

`audit_scene(seed)` draws one scene, the same for every model:
- 3-5 library vehicles (crashlab.vehicle.library(), every one of them, bus included) at 0-90 km/h (one in
  five standing), each on a straight path that passes the origin at a lateral offset of up to 1.5 m; the first
  two are due at the origin at the same moment t_meet (0.6-1.2 s), so at least these two meet, the others up
  to 1 s before or after, so more join at staggered times; a standing vehicle stands within 4 m of the origin;
- driver actions on about half the vehicles: one or two, each braking (0-1, ramp 0-0.3 s), steering (up to
  +/-20 deg, ramp 0-0.3 s) or locking the wheels, at random times 0.1-3 s;
- 0-2 friction zones (a rotated rectangle or a triangle near the origin, friction 0.1-1.0) on a road of
  0.3-1.0;
- a rigid barrier in 3 scenes of 10, 5-12 m from the origin across the paths;
- restitution 0-0.4, vehicle-vehicle friction 0.1-0.6, the three impulse laws; 6 s, stopping at rest.
A draw whose outlines overlap at the start (vehicles or barriers) is redrawn (crashlab.scene.start_overlaps
and the scene reader's own check)."""
from __future__ import annotations

import math

import numpy as np

from crashlab.errors import InputError
from crashlab.scene import start_overlaps
from crashlab.scene_file import scene_from_dict
from crashlab.vehicle import library

DURATION = 6.0  # s
MAX_TRIES = 50


def _zone(rng) -> dict:
    cx, cy = rng.uniform(-8, 8, size=2)
    if rng.random() < 0.5:  # a rotated rectangle
        a, hw, hh = rng.uniform(0, math.pi), rng.uniform(1, 8), rng.uniform(1, 8)
        c, s = math.cos(a), math.sin(a)
        pts = [(cx + c * u - s * w, cy + s * u + c * w) for u, w in ((-hw, -hh), (hw, -hh), (hw, hh), (-hw, hh))]
    else:  # a triangle (three angles in order around its centre)
        ang = np.sort(rng.uniform(0, 2 * math.pi, size=3))
        r = rng.uniform(2, 8, size=3)
        pts = [(cx + rk * math.cos(ak), cy + rk * math.sin(ak)) for rk, ak in zip(r, ang)]
    return {"friction": float(rng.uniform(0.1, 1.0)), "polygon": [[float(x), float(y)] for x, y in pts]}


def _actions(rng) -> list[dict]:
    acts = []
    for t in np.sort(rng.uniform(0.1, 3.0, size=int(rng.integers(1, 3)))):
        kind = rng.choice(["brake", "steer", "lock"])
        if kind == "brake":
            acts.append({"t": float(t), "brake": float(rng.uniform(0, 1)), "ramp": float(rng.uniform(0, 0.3))})
        elif kind == "steer":
            acts.append({"t": float(t), "steer": float(rng.uniform(-20, 20)), "ramp": float(rng.uniform(0, 0.3))})
        else:
            acts.append({"t": float(t), "wheels": "locked"})
    if len(acts) == 2 and acts[1]["t"] - acts[0]["t"] < 1e-3:
        acts = acts[:1]
    for a, b in zip(acts, acts[1:]):  # a ramp ends before the next action
        if "ramp" in a:
            a["ramp"] = min(a["ramp"], 0.9 * (b["t"] - a["t"]))
    return acts


def _draw(rng, seed: int) -> dict:
    kinds = library()
    n = int(rng.integers(3, 6))
    t_meet = float(rng.uniform(0.6, 1.2))
    vehicles = []
    for i in range(n):
        heading = float(rng.uniform(0, 360))
        a = math.radians(heading)
        speed = 0.0 if (i > 0 and rng.random() < 0.2) else float(rng.uniform(15, 90))
        v = {"name": f"V{i + 1}", "vehicle": str(rng.choice(kinds)), "heading": heading, "speed": speed,
             "wheels": str(rng.choice(["rolling", "rolling", "braked", "locked_after_impact"]))}
        if speed == 0.0:
            x, y = rng.uniform(-4, 4, size=2)
        else:
            t_i = t_meet if i < 2 else t_meet + float(rng.uniform(-1.0, 1.0))
            d, off = speed / 3.6 * max(t_i, 0.3), float(rng.uniform(-1.5, 1.5))
            # along the heading back from the origin, shifted sideways by the offset
            x, y = -d * math.cos(a) - off * math.sin(a), -d * math.sin(a) + off * math.cos(a)
        v |= {"x": float(x), "y": float(y)}
        if rng.random() < 0.5:
            v["actions"] = _actions(rng)
        vehicles.append(v)
    barriers = []
    if rng.random() < 0.3:
        a, r = rng.uniform(0, 2 * math.pi), rng.uniform(5, 12)
        barriers.append({"x": float(r * math.cos(a)), "y": float(r * math.sin(a)),
                         "heading": float(math.degrees(a) + 90), "length": float(rng.uniform(4, 12)),
                         "width": float(rng.uniform(0.5, 1.0))})
    zones = [_zone(rng) for _ in range(int(rng.integers(0, 3)))]
    return {"name": f"audit {seed}", "duration": DURATION, "stop_at_rest": True,
            "road": {"friction": float(rng.uniform(0.3, 1.0)), "zones": zones},
            "impact": {"restitution": float(rng.uniform(0, 0.4)), "friction": float(rng.uniform(0.1, 0.6)),
                       "law": str(rng.choice(["kudlich-slibar", "brach", "routh"]))},
            "vehicles": vehicles, "barriers": barriers}


def audit_scene_dict(seed: int) -> dict:
    """The scene file dict (file units) of the audit scene `seed`: the first draw of the seeded generator
    without overlapping outlines at the start."""
    rng = np.random.default_rng([27, seed])
    for _ in range(MAX_TRIES):
        data = _draw(rng, seed)
        try:
            scene = scene_from_dict(data, source=data["name"])
        except InputError as err:
            if "overlap" not in str(err):
                raise
            continue
        if not start_overlaps(scene):
            return data
    raise RuntimeError(f"audit scene {seed}: no draw without overlaps in {MAX_TRIES} tries")


def audit_scene(seed: int):
    data = audit_scene_dict(seed)
    return scene_from_dict(data, source=data["name"])
