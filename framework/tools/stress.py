"""Stress sweep: seeded random scenes, simulated and judged by the physics guard.

`random_scenes(n, seed)` draws two-vehicle crashes from a documented space: library vehicles with their mass
overridden to 700-3000 kg (inertias scaled with the mass), speeds 5-200 km/h (the struck car standing in a
quarter of the scenes), any impact angle, a lateral offset of the paths up to 1 m, every wheel state,
restitution 0-0.5, vehicle-vehicle friction 0.1-0.6, road friction 0.3-1.0, the three impulse laws, and a rigid
barrier in one scene of eight; `extreme_scenes()` adds 200 km/h into a wall, into a standing car and
head-on, 700 against 3000 kg, and a 2 deg grazing contact. `sweep(model, scenes)` runs each scene and tabulates
what the guard says.

Command: `crashlab stress --model NAME [--runs N] [--seed S] [--csv FILE]`.
"""
from __future__ import annotations

import math
import time

import numpy as np

from ..errors import InputError
from ..scene import start_overlaps
from ..scene_file import scene_from_dict

VEHICLES = ("clio", "saloon", "suv")
WHEEL_STATES = ("rolling", "locked", "locked_after_impact", "braked")
MASS_RANGE = (700.0, 3000.0)  # kg
SPEED_RANGE = (5.0, 200.0)  # km/h
DURATION = 10.0  # s


def _vehicle_overrides(kind: str, mass: float) -> dict:
    from ..vehicle import load_vehicle
    spec = load_vehicle(kind)
    k = mass / spec.mass
    return {"mass": mass, "yaw_inertia": spec.yaw_inertia * k, "roll_inertia": spec.roll_inertia * k,
            "pitch_inertia": spec.pitch_inertia * k}


def _crash(name: str, v1: dict, v2: dict | None, angle: float, offset: float, impact: dict, road: float,
           barrier: bool, t_meet: float = 0.4) -> dict:
    """A scene dict whose vehicles' paths cross at the origin: V1 on heading 0 (its path `offset` [m] to the
    side), V2 on heading `angle` [deg] (or standing there), both CGs due there `t_meet` after the start, so
    they meet before."""
    vehicles = []
    s1 = v1["speed"] / 3.6
    vehicles.append({"name": "V1", "vehicle": v1["kind"], "x": -s1 * t_meet, "y": offset, "heading": 0.0,
                     "speed": v1["speed"], "wheels": v1["wheels"],
                     "overrides": _vehicle_overrides(v1["kind"], v1["mass"])})
    barriers = []
    if barrier:
        barriers.append({"x": 0.5, "y": 0.0, "heading": angle + 90.0, "length": 6.0, "width": 1.0})
    if v2 is not None:
        gap2 = v2["speed"] / 3.6 * t_meet
        a = math.radians(angle)
        vehicles.append({"name": "V2", "vehicle": v2["kind"], "x": -gap2 * math.cos(a), "y": -gap2 * math.sin(a),
                         "heading": angle, "speed": v2["speed"], "wheels": v2["wheels"],
                         "overrides": _vehicle_overrides(v2["kind"], v2["mass"])})
    return {"name": name, "duration": DURATION, "stop_at_rest": True, "road": {"friction": road},
            "impact": impact, "vehicles": vehicles, "barriers": barriers}


def crash_scene(*args):
    """Two vehicles placed to collide: the first scene of _crash(*args, t_meet) without overlapping outlines
    at the start, t_meet from 0.4 s up to 4 s (vehicles on nearly the same path at nearly the same speed
    never part: None)."""
    for t_meet in np.arange(0.4, 4.0, 0.2):
        data = _crash(*args, t_meet=t_meet)
        try:
            scene = scene_from_dict(data, source=data["name"])
        except InputError as err:  # overlapping at the start is the only error a drawn scene can have
            if "overlap" not in str(err):
                raise
            continue
        if not start_overlaps(scene):
            return scene
    return None


def random_scenes(n: int, seed: int = 0) -> list:
    """n seeded random crash scenes (see the module docstring for the space)."""
    rng = np.random.default_rng(seed)
    scenes = []
    k = 0
    while len(scenes) < n:
        def car():
            return {"kind": str(rng.choice(VEHICLES)), "mass": float(rng.uniform(*MASS_RANGE)),
                    "speed": float(rng.uniform(*SPEED_RANGE)), "wheels": str(rng.choice(WHEEL_STATES))}
        v1 = car()
        barrier = rng.random() < 0.125
        v2 = None if barrier and rng.random() < 0.5 else car()
        if v2 is not None and rng.random() < 0.25:
            v2["speed"] = 0.0
        impact = {"restitution": float(rng.uniform(0.0, 0.5)), "friction": float(rng.uniform(0.1, 0.6)),
                  "law": str(rng.choice(["kudlich-slibar", "brach", "routh"]))}
        scene = crash_scene(f"random {seed}:{k}", v1, v2, float(rng.uniform(0, 360)), float(rng.uniform(-1, 1)),
                       impact, float(rng.uniform(0.3, 1.0)), barrier)
        k += 1
        if scene is not None:
            scenes.append(scene)
    return scenes


def extreme_scenes() -> list:
    """The corners of the space: 200 km/h into a wall, into a standing car, head-on; 700 against 3000 kg;
    a 2 deg grazing contact."""
    imp = {"restitution": 0.1, "friction": 0.3}

    def car(kind="clio", mass=1000.0, speed=200.0, wheels="rolling"):
        return {"kind": kind, "mass": mass, "speed": speed, "wheels": wheels}

    specs = [
        ("200 km/h into a wall", car(), None, 180.0, 0.0, True),
        ("200 km/h into a standing car", car(), car("saloon", 1500.0, 0.0), 90.0, 0.0, False),
        ("200 km/h head-on", car(), car("saloon", 1500.0), 180.0, 0.0, False),
        ("700 kg against 3000 kg", car(mass=700.0, speed=80.0), car("suv", 3000.0, 80.0), 180.0, 0.3, False),
        ("2 deg grazing contact", car(speed=100.0), car("saloon", 1500.0, 100.0), 178.0, 1.7, False),
    ]
    return [crash_scene(name, v1, v2, angle, offset, imp, 0.8, barrier)
            for name, v1, v2, angle, offset, barrier in specs]


def sweep(model, scenes):
    """Run every scene; one row per run: scene, speeds, masses, wheel states, ok, violations, reason,
    vehicles still moving at the end, wall time."""
    import pandas as pd
    rows = []
    for scene in scenes:
        t0 = time.perf_counter()
        try:
            out = model.simulate(scene)
            ok, kinds = out.outcome_ok, list(out.violations)
            reason = "" if ok else "; ".join(out.warnings)
            if not ok and not kinds:
                kinds = ["model_failure"]
            moving = [n for n, r in zip(out.names, out.at_rest_mask) if not r] if ok else []
            rolled = list(out.rolled_over)
            impacts = len(out.impact_energy)
        except Exception as err:  # a model that raises is a failure of the model, recorded as such
            ok, kinds, reason, moving, rolled = False, ["exception"], f"{type(err).__name__}: {err}", [], []
            impacts = 0
        vs = scene.vehicles
        rows.append({"scene": scene.name, "n_vehicles": len(vs), "barriers": len(scene.barriers),
                     "speeds_kmh": "/".join(f"{v.speed * 3.6:.0f}" for v in vs),
                     "masses_kg": "/".join(f"{v.spec.mass:.0f}" for v in vs),
                     "wheels": "/".join(v.wheels for v in vs), "impacts": impacts, "ok": ok,
                     "violations": ",".join(kinds), "reason": reason, "moving_at_end": ",".join(moving),
                     "rolled_over": ",".join(rolled),
                     "wall_time_s": time.perf_counter() - t0})
    return pd.DataFrame(rows)


def summary(df) -> dict:
    """Runs, caught runs and caught runs by kind."""
    kinds: dict = {}
    for v in df.violations:
        for k in filter(None, v.split(",")):
            kinds[k] = kinds.get(k, 0) + 1
    return {"runs": len(df), "caught": int((~df.ok).sum()), "by_kind": kinds,
            "moving_at_end": int((df.moving_at_end != "").sum()), "rolled_over": int((df.rolled_over != "").sum())}
