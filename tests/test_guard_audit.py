"""An independent audit of the physics guard (issue 27, Done-when): random 3-5 vehicle scenes with driver
actions, friction zones and barriers (tests/audit_scenes.py) run through each built-in model, and every
Outcome judged twice: by the guard (crashlab.guard, inside the model) and by the physics written here from
the scene and the Outcome's numbers alone (no call into crashlab.guard, crashlab.geometry or the models).

Independent check (`audit`), each with its stated tolerance:
- finite: no NaN or inf in the end state, any trajectory column or any impact row's number;
- energy: per vehicle, its energy (planar 1/2 m v^2 + 1/2 Iz r^2; 3D the rigid body's full energy with the
  rates from the recorded angles: `_energy`; masses and inertias from the scene's vehicle specs) never rises,
  within a stretch of samples where it touches nothing, by more than ENERGY_TOL_J + ENERGY_TOL_REL x its
  largest energy; "touches" = its rectangle lies within CONTACT_GAP (+ the distance the two close in one
  sample) of another vehicle's or a barrier's at either end of the step (separating-axis distance written
  here), or an impact row of it spans the step (the road gives no energy: docs/physics.md, "Physics guard");
  a 3D vehicle whose own recorded mechanical energy (springs included) stays within the tolerance over the
  stretch is an elastic release, not a gain (`_elastic_release`);
- end balance: total planar kinetic energy at the end <= at the start + ENERGY_TOL_J + ENERGY_TOL_REL x start;
- impact rows: every row's dissipated energy >= -(ENERGY_TOL_J + ENERGY_TOL_REL x start);
- overlap at rest: no two outlines (vehicles, barriers) overlap by more than OVERLAP_TOL: rectangles for the
  planar models; for multibody and exudyn the plan shadows of their superellipsoid bodies (`rounded_outline`)
  by more than OVERLAP_TOL + the permanent crush the pair can keep (`crush_bound`; a vehicle ending tilted
  beyond TILT_MAX is left out: its shadow is another);
- rest: a vehicle reported at rest has end speed <= 0.1 m/s, and its trajectory's last speed <= 1 m/s;
  the end state matches the trajectory's last sample within 1 m / 1 m/s;
- box: every trajectory sample within BOX m of the origin; no body below the road by more than 5 cm (z_min).

Classes of a run: ok (guard ok, audit clean), silent (guard ok, audit finds a violation: must be 0),
false_alarm? (guard failed it, audit clean: each looked at), caught (failed with a reason, audit agrees),
failed: <cause> (a model failure with a reason that is no guard verdict, e.g. a solver error), no_reason
(failed with no reason: must be 0), exception (the model raised).
"""
from __future__ import annotations

import math
import time
from collections import Counter

import numpy as np
import pytest
from audit_scenes import audit_scene
from scipy.spatial.transform import Rotation

import crashlab

G = 9.81  # m/s^2
ENERGY_TOL_J = 1000.0  # J: the guard's documented tolerance (README, "the physics guard")
ENERGY_TOL_REL = 0.02
CONTACT_GAP = 0.3  # m between rectangles that counts as touching (3D bodies lean and crush beyond the outline)
OVERLAP_TOL = 0.05  # m of outline overlap at rest (the guard's PENETRATION_TOL)
TILT_MAX = math.radians(30)  # rad of roll or pitch at the end beyond which a 3D body's plan shadow is another
REST_SPEED = 0.1  # m/s: at rest
BOX = 400.0  # m: 90 km/h for 6 s is 150 m
# below the road (docs/physics.md §19): deeper than ROAD_TOL_DEEP at any sample, or the depth below the road
# averaging more than ROAD_TOL over ROAD_SUSTAINED_S (a landing bounce off the road contact is brief)
ROAD_TOL, ROAD_TOL_DEEP, ROAD_SUSTAINED_S = 0.05, 0.10, 0.1  # m, m, s
END_POSE_TOL, END_VEL_TOL = 1.0, 1.0  # m, m/s: end state against the trajectory's last sample

COUNTS = {"impulse": 300, "pymunk": 60, "multibody": 30, "exudyn": 12}


# ------------------------------------------------------------------ independent geometry (separating axes)
def rectangle(x, y, heading, front, rear, half_width) -> np.ndarray:
    """Corners (4, 2) of a rectangle: front/rear along the heading from (x, y), half_width across."""
    c, s = math.cos(heading), math.sin(heading)
    local = np.array([(front, half_width), (-rear, half_width), (-rear, -half_width), (front, -half_width)])
    return np.column_stack((x + c * local[:, 0] - s * local[:, 1], y + s * local[:, 0] + c * local[:, 1]))


def sat_overlap(a: np.ndarray, b: np.ndarray) -> float:
    """Signed separation of two convex polygons over the edge normals of both (separating-axis theorem):
    the smallest overlap of their projections, > 0 overlapping by that depth, < 0 apart (then minus the
    largest gap over the axes: a lower bound of the distance, exact for a face-to-face gap)."""
    best = math.inf
    for poly in (a, b):
        edges = np.roll(poly, -1, axis=0) - poly
        for ex, ey in edges:
            n = np.array([-ey, ex]) / math.hypot(ex, ey)
            pa, pb = a @ n, b @ n
            best = min(best, min(pa.max(), pb.max()) - max(pa.min(), pb.min()))
    return best


def vehicle_rect(v, x, y, h) -> np.ndarray:
    s = v.spec
    return rectangle(x, y, h, s.cg_to_front, s.cg_to_rear, s.width / 2)


def rounded_outline(v, x, y, h, corners: int = 64) -> np.ndarray:
    """Plan shadow of a 3D model's upright chassis body (models/common/vehicle_3d.py, chassis_shape's default,
    the Clio's own table the same): the superellipse |u/a|^4 + |w/b|^4 = 1, a = length / 2 centred between
    the bumpers, b = width / 2, as a convex polygon. A bus's corner lies ~1 m inside its rectangle's."""
    s = v.spec
    a, b, off = (s.cg_to_front + s.cg_to_rear) / 2, s.width / 2, (s.cg_to_front - s.cg_to_rear) / 2
    th = np.linspace(0, 2 * np.pi, corners, endpoint=False)
    u = off + a * np.sign(np.cos(th)) * np.sqrt(np.abs(np.cos(th)))
    w = b * np.sign(np.sin(th)) * np.sqrt(np.abs(np.sin(th)))
    c, sn = math.cos(h), math.sin(h)
    return np.column_stack((x + c * u - sn * w, y + sn * u + c * w))


def barrier_rect(b) -> np.ndarray:
    return rectangle(b.x, b.y, b.heading, b.length / 2, b.length / 2, b.width / 2)


# ------------------------------------------------------------------ the audit
def crush_bound(out, a, b=None) -> float:
    """The deepest permanent crush [m] vehicles a and b (or a and a rigid barrier: b None) can keep together,
    from Campbell's crash plot EBS = b0 + b1 C with the library's softest class line (side: b0 = 0.9 m/s,
    b1 = (7.0 - 0.9) / 0.30 = 20.3 1/s; docs/physics.md §28): each vehicle's EBS is at most the pair's largest
    closing speed over the run (its share of the dissipated energy is at most 1/2 mu v_rel^2, mu <= its
    mass), so each keeps at most (v_rel - b0) / b1. The 3D models keep such crush (docs/physics.md §13a):
    their undeformed bodies overlap by it at rest."""
    b0, b1 = 0.9, (7.0 - 0.9) / 0.30
    ta = out.trajectories.get(a.name)
    tb = None if b is None else out.trajectories.get(b.name)
    if ta is None or (b is not None and tb is None):
        return 0.0
    if b is None:
        v = float(np.max(np.hypot(ta["vx"], ta["vy"])))
        return max(v - b0, 0.0) / b1
    v = float(np.max(np.hypot(np.subtract(ta["vx"], tb["vx"]), np.subtract(ta["vy"], tb["vy"]))))
    return 2 * max(v - b0, 0.0) / b1


def _energy(v, tr) -> tuple[np.ndarray, np.ndarray]:
    """(times, energy [J]) of one vehicle from its trajectory: planar, at the samples, 1/2 m v^2 + 1/2 Iz r^2;
    3D (the trajectory records z, roll and pitch), at the middle of each step, the rigid body's full energy
    1/2 m (vx^2 + vy^2 + vz^2) + 1/2 (Ix p^2 + Iy q^2 + Iz r^2) + m g (z - z0), with vz = dz/dt and the body
    rates (p, q, r) from the rotation between two samples (ZYX angles heading, pitch, roll; scipy), the
    inertias the spec's roll, pitch and yaw inertias. A car tumbling in the air trades yaw rate for roll
    rate: its planar energy rises by 10 kJ (multibody, audit scene 12, V2 at 1.8-2.15 s) where this one holds
    within 0.5 kJ."""
    s = v.spec
    m, t = s.mass, np.asarray(tr["t"], dtype=float)
    if not all(k in tr for k in ("z", "roll", "pitch")) or len(t) < 2:
        return t, 0.5 * m * (np.square(tr["vx"]) + np.square(tr["vy"])) + 0.5 * s.yaw_inertia * np.square(
            tr["yaw_rate"])
    dt = np.diff(t)
    rot = Rotation.from_euler("ZYX", np.column_stack([tr["heading"], tr["pitch"], tr["roll"]]))
    w = (rot[:-1].inv() * rot[1:]).as_rotvec() / dt[:, None]  # body frame, over each step

    def mid(a):
        a = np.asarray(a, dtype=float)
        return 0.5 * (a[1:] + a[:-1])

    vz = np.diff(np.asarray(tr["z"], dtype=float)) / dt
    e = 0.5 * m * (mid(tr["vx"]) ** 2 + mid(tr["vy"]) ** 2 + vz ** 2) + m * G * (mid(tr["z"]) - tr["z"][0]) \
        + 0.5 * (s.roll_inertia * w[:, 0] ** 2 + s.pitch_inertia * w[:, 1] ** 2 + s.yaw_inertia * w[:, 2] ** 2)
    return mid(t), e


def _elastic_release(tr, times, tol) -> bool:
    """A 3D vehicle's rigid-body energy (`_energy`) rising over `times` while its own mechanical energy, as the
    model records it (trajectory column "energy": the chassis and wheels with the suspension's and tyres' springs),
    does not rise by more than `tol`: the springs give back what a tripping or landing body stored in them, which
    the rigid-body estimate does not count (audit seed 25, multibody, with the first build of the crush-profile
    force of 2026-11-27: a Metro tripped sideways at 4.8 m/s rises 7.1 kJ rigid, 2.1 kJ in the model's energy,
    thrown 1 m up). False where the column is missing."""
    if "energy" not in tr or len(times) < 2:
        return False
    em = np.interp(times, np.asarray(tr["t"], dtype=float), np.asarray(tr["energy"], dtype=float))
    return float(np.max(em[1:] - np.minimum.accumulate(em)[:-1])) <= tol


def _touching(scene, out, t) -> np.ndarray:
    """(nv, len(t) - 1): vehicle i touches another vehicle or a barrier during step k (samples k, k+1)."""
    vs, trs = scene.vehicles, out.trajectories
    nv, nt = len(vs), len(t)
    near = np.zeros((nv, nt), dtype=bool)
    dt = float(np.max(np.diff(t))) if nt > 1 else 0.0
    pos = {}
    for v in vs:
        tr = trs[v.name]
        pos[v.name] = np.column_stack([np.interp(t, tr["t"], tr[k]) for k in ("x", "y", "heading", "vx", "vy")])
    reach = [math.hypot(max(v.spec.cg_to_front, v.spec.cg_to_rear), v.spec.width / 2) for v in vs]
    bars = [(barrier_rect(b), (b.x, b.y), math.hypot(b.length, b.width) / 2) for b in scene.barriers]
    for k in range(nt):
        rects = [vehicle_rect(v, *pos[v.name][k, :3]) for v in vs]
        for i in range(nv):
            pi = pos[vs[i].name][k]
            for j in range(i + 1, nv):
                pj = pos[vs[j].name][k]
                margin = CONTACT_GAP + math.hypot(pi[3] - pj[3], pi[4] - pj[4]) * dt
                if math.hypot(pi[0] - pj[0], pi[1] - pj[1]) > reach[i] + reach[j] + margin:
                    continue
                if sat_overlap(rects[i], rects[j]) > -margin:
                    near[i, k] = near[j, k] = True
            for rect, (bx, by), rb in bars:
                margin = CONTACT_GAP + math.hypot(pi[3], pi[4]) * dt
                if math.hypot(pi[0] - bx, pi[1] - by) > reach[i] + rb + margin:
                    continue
                if sat_overlap(rects[i], rect) > -margin:
                    near[i, k] = True
    touch = near[:, 1:] | near[:, :-1]
    for r in out.impact_rows:  # the model's own contacts count too (a contact may act between samples)
        i = scene.vehicle_names.index(r["vehicle"])
        t1 = r.get("t_end", r["t"] + r.get("duration", 0.0))
        touch[i] |= (t[1:] >= r["t"] - 1e-3) & (t[:-1] <= t1 + 1e-3)
    return touch


def _below_road(t, z) -> bool:
    """A body deeper than ROAD_TOL_DEEP at a sample, or its depth below the road (linear between the samples,
    resampled every millisecond here) averaging more than ROAD_TOL over a window of ROAD_SUSTAINED_S."""
    if np.nanmin(z) < -ROAD_TOL_DEEP:
        return True
    grid = np.arange(t[0], t[-1] + 1e-12, 1e-3)
    depth = np.interp(grid, t, np.nan_to_num(np.maximum(-z, 0.0)))
    n = int(round(ROAD_SUSTAINED_S / 1e-3))
    if len(grid) <= n:
        return False
    mean = np.convolve(depth, np.ones(n) / n, mode="valid")
    return bool(mean.max() > ROAD_TOL + 1e-4)  # (the millisecond grid's own error is below it)


def audit(scene, out, rounded: bool, worst: dict | None = None) -> list[str]:
    """Every violation of physics the independent checks find in `out` (empty: clean). `worst`, if given,
    keeps the largest value / tolerance seen per check (how near a clean run came to a finding)."""
    found = []
    worst = {} if worst is None else worst

    def near(check, ratio):
        worst[check] = max(worst.get(check, 0.0), float(ratio))
    vs = scene.vehicles
    rest, final = np.asarray(out.rest_si, float), np.asarray(out.final_si, float)
    if not (np.isfinite(rest).all() and np.isfinite(final).all()):
        return ["non_finite: end state"]
    for v in vs:
        for col, a in out.trajectories.get(v.name, {}).items():
            if not np.isfinite(np.asarray(a, dtype=float)).all():
                return [f"non_finite: {v.name}'s {col}"]
    rows = out.impact_rows
    for r in rows:
        for col, val in r.items():
            if isinstance(val, float) and not math.isfinite(val):
                return [f"non_finite: impact row {col}"]
    mass = np.array([v.spec.mass for v in vs])
    iz = np.array([v.spec.yaw_inertia for v in vs])
    e0 = float(np.sum(0.5 * mass * np.square([v.speed for v in vs]) + 0.5 * iz * np.square([v.yaw_rate for v in vs])))
    e1 = float(np.sum(0.5 * mass * (final[:, 0] ** 2 + final[:, 1] ** 2) + 0.5 * iz * final[:, 2] ** 2))
    tol0 = ENERGY_TOL_J + ENERGY_TOL_REL * e0
    near("energy_end", (e1 - e0) / tol0)
    if e1 - e0 > tol0:
        found.append(f"energy_end: {e1 / 1e3:.1f} kJ at the end, {e0 / 1e3:.1f} kJ at the start")
    for r in rows:
        near("impact_energy", -r["energy"] / tol0)
        if r["energy"] < -tol0:
            found.append(f"impact_energy: {r['vehicle']}-{r['other']} at t = {r['t']:.3f} s: "
                         f"{r['energy'] / 1e3:.1f} kJ")
            break
    # at rest, and the end state against the trajectory's end
    speed = np.hypot(final[:, 0], final[:, 1])
    table = out.rest
    for i, v in enumerate(vs):
        if bool(table["at_rest"].iloc[i]) and speed[i] > REST_SPEED:
            found.append(f"rest: {v.name} at rest at {speed[i]:.2f} m/s")
        tr = out.trajectories.get(v.name)
        if not tr or not len(tr["t"]):
            continue
        last = np.array([tr[k][-1] for k in ("x", "y", "vx", "vy")], dtype=float)
        if bool(table["at_rest"].iloc[i]) and math.hypot(last[2], last[3]) > END_VEL_TOL:
            found.append(f"rest: {v.name} at rest, its trajectory ends at {math.hypot(last[2], last[3]):.2f} m/s")
        if np.any(np.abs(last[:2] - rest[i, :2]) > END_POSE_TOL) \
                or np.any(np.abs(last[2:] - final[i, :2]) > END_VEL_TOL):
            found.append(f"end_state: {v.name}'s end state is not its trajectory's end")
        if np.max(np.hypot(tr["x"], tr["y"])) > BOX:
            found.append(f"box: {v.name} leaves the {BOX:.0f} m box")
        if "z_min" in tr and _below_road(np.asarray(tr["t"]), np.asarray(tr["z_min"])):
            found.append(f"below_road: {v.name} {-np.min(tr['z_min']):.2f} m below the road")
    # energy outside contact, per vehicle
    if out.trajectories and all(v.name in out.trajectories for v in vs):
        t = np.asarray(out.trajectories[vs[0].name]["t"], dtype=float)
        if len(t) > 1:
            touch = _touching(scene, out, t)
            for i, v in enumerate(vs):
                te, e = _energy(v, out.trajectories[v.name])
                if len(te) == len(t):  # at the samples: a touched step k (samples k, k + 1) starts a stretch at k + 1
                    starts = np.concatenate(([0], np.flatnonzero(touch[i]) + 1))
                    stretches = zip(starts, np.append(starts[1:], len(t)))
                    times = t
                else:  # 3D: one energy per step; the touched steps are left out
                    e = np.interp(0.5 * (t[1:] + t[:-1]), te, e)
                    free = np.flatnonzero(~touch[i])
                    cut = np.flatnonzero(np.diff(free) > 1) + 1
                    stretches = [(g[0], g[-1] + 1) for g in np.split(free, cut) if len(g)]
                    times = 0.5 * (t[1:] + t[:-1])
                tol = ENERGY_TOL_J + ENERGY_TOL_REL * float(np.max(np.abs(e)))
                for s, end in stretches:
                    seg = e[s:end]
                    if len(seg) < 2:
                        continue
                    rise = seg[1:] - np.minimum.accumulate(seg)[:-1]
                    k = int(np.argmax(rise))
                    near("energy_free", rise[k] / tol)
                    if rise[k] > tol and _elastic_release(out.trajectories[v.name], times[s:end], tol):
                        near("energy_free_elastic", rise[k] / tol)
                    elif rise[k] > tol:
                        found.append(f"energy_free: {v.name} gains {rise[k] / 1e3:.1f} kJ touching nothing "
                                     f"(by t = {times[s + 1 + k]:.2f} s; tolerance {tol / 1e3:.1f} kJ)")
                        break
    # overlap at rest (3D models: the upright bodies' plan shadows, less the permanent crush the pair may
    # keep, `crush_bound`; a vehicle tilted beyond TILT_MAX has another shadow and is left out of this check)
    tilted = [bool(rounded and v.name in out.trajectories and "roll" in out.trajectories[v.name]
                   and max(abs(math.remainder(float(out.trajectories[v.name][k][-1]), 2 * math.pi))
                           for k in ("roll", "pitch")) > TILT_MAX) for v in vs]
    shape = rounded_outline if rounded else vehicle_rect
    outlines = [shape(v, *rest[i]) for i, v in enumerate(vs)]
    others = [(f"barrier {k}", barrier_rect(b), None) for k, b in enumerate(scene.barriers)]
    for i in range(len(vs)):
        if tilted[i]:
            continue
        pairs = [(vs[j].name, outlines[j], j) for j in range(i + 1, len(vs)) if not tilted[j]] + others
        for name, outline, j in pairs:
            depth = sat_overlap(outlines[i], outline)
            tol = OVERLAP_TOL + (crush_bound(out, vs[i], None if j is None else vs[j]) if rounded else 0.0)
            near("overlap", depth / tol)
            if depth > tol:
                found.append(f"overlap: {vs[i].name} and {name} end {depth:.2f} m into each other "
                             f"(tolerance {tol:.2f} m)")
    return found


GUARD = "physics guard: "


def classify(scene, model, rounded: bool, worst: dict | None = None) -> tuple[str, str, list[str]]:
    """(class, cause, audit findings) of one run (see the module docstring); `worst` (optional) gathers the
    margins of the runs the guard passed (see `audit`)."""
    try:
        out = model.simulate(scene)
    except Exception as err:  # noqa: BLE001 - a model that raises is recorded, not hidden
        return "exception", f"{type(err).__name__}: {err}"[:80], []
    found = audit(scene, out, rounded, worst if out.outcome_ok else None)
    if out.outcome_ok:
        return ("silent" if found else "ok"), "", found
    reasons = [w for w in out.warnings if w.startswith(GUARD)]
    if reasons:
        cause = reasons[0][len(GUARD):].split(":")[0]
        return ("caught" if found else "false_alarm?"), cause, found
    if not out.warnings:
        return "no_reason", "", found
    return "failed", " ".join(out.warnings[-1].split()[:5]), found


def run_audit(model_name: str, seeds) -> tuple[Counter, list, dict]:
    """(counts per class and cause, (seed, class, cause, findings) of every run not ok, the worst margins of
    the passed runs: value / tolerance per check)."""
    model = crashlab.get_model(model_name)
    rounded = model_name in ("multibody", "exudyn")
    counts, notes, worst = Counter(), [], {}
    for seed in seeds:
        scene = audit_scene(seed)
        cls, cause, found = classify(scene, model, rounded, worst)
        counts[f"{cls}: {cause}" if cause else cls] += 1
        if cls not in ("ok",):
            notes.append((seed, cls, cause, found))
    return counts, notes, worst


def _print_table(model_name, counts, notes, wall, worst):
    print(f"\n== {model_name}: {sum(counts.values())} runs in {wall:.0f} s")
    print("   largest value / tolerance in the passed runs: "
          + ", ".join(f"{k} {v:.2f}" for k, v in sorted(worst.items())))
    for k, n in sorted(counts.items()):
        print(f"   {n:4d}  {k}")
    for seed, cls, cause, found in notes:
        print(f"   seed {seed}: {cls} {cause} {'; '.join(found)[:300]}")


def _assert_clean(counts):
    bad = {k: n for k, n in counts.items() if k.split(":")[0] in ("silent", "no_reason", "exception")}
    assert not bad, bad


# ------------------------------------------------------------------ the audit's own checks can fail
def test_sat_against_an_analytic_overlap():
    """Two axis-aligned 4 x 2 rectangles 3.9 m apart overlap by 0.1 m; rotated by 90 deg about its centre the
    second (2 x 4) is 0.9 m apart: 2 + 1 - 3.9 = -0.9."""
    a = rectangle(0, 0, 0, 2, 2, 1)
    assert sat_overlap(a, rectangle(3.9, 0, 0, 2, 2, 1)) == pytest.approx(0.1)
    assert sat_overlap(a, rectangle(3.9, 0, math.pi / 2, 2, 2, 1)) == pytest.approx(-0.9)


def test_3d_energy_of_a_free_flight_against_the_analytic_value():
    """A body thrown upward (vz0 = 5 m/s, vx = 10 m/s) spinning at 6 rad/s about its roll axis while pitched
    0.3 rad and yawed 0.5 rad (a steady spin about a principal axis: torque-free): its energy is
    1/2 m (vx^2 + vz0^2) + 1/2 Ix w^2 at every step (gravity turns vz into height), within 0.5 %."""
    from types import SimpleNamespace
    spec = SimpleNamespace(mass=1200.0, roll_inertia=500.0, pitch_inertia=2000.0, yaw_inertia=2200.0)
    t = np.arange(0.0, 1.0, 0.01)
    roll = np.remainder(6.0 * t + math.pi, 2 * math.pi) - math.pi  # recorded wrapped, as atan2 gives it
    tr = {"t": t, "vx": np.full_like(t, 10.0), "vy": np.zeros_like(t),
          "yaw_rate": np.full_like(t, -6.0 * math.sin(0.3)), "heading": np.full_like(t, 0.5),
          "pitch": np.full_like(t, 0.3), "roll": roll,
          "z": 0.5 + 5.0 * t - 0.5 * G * t ** 2}
    _, e = _energy(SimpleNamespace(spec=spec), tr)
    exact = 0.5 * 1200.0 * (10.0 ** 2 + 5.0 ** 2) + 0.5 * 500.0 * 6.0 ** 2
    assert np.allclose(e, exact, rtol=5e-3)


def test_rounded_outline_against_the_superellipse():
    """The plan shadow's area is the superellipse's 4 a b Gamma(5/4)^2 / Gamma(3/2) (within 1 %), and two such
    Clios nose to nose 0.1 m closer than their length overlap by 0.1 m (SAT along the axis)."""
    from types import SimpleNamespace
    spec = SimpleNamespace(cg_to_front=2.0, cg_to_rear=1.8, width=1.7)
    v = SimpleNamespace(spec=spec)
    p = rounded_outline(v, 0.0, 0.0, 0.3)
    area = 0.5 * abs(np.dot(p[:, 0], np.roll(p[:, 1], -1)) - np.dot(p[:, 1], np.roll(p[:, 0], -1)))
    exact = 4 * 1.9 * 0.85 * math.gamma(1.25) ** 2 / math.gamma(1.5)
    assert area == pytest.approx(exact, rel=0.01)
    a = rounded_outline(v, 0.0, 0.0, 0.0)
    b = rounded_outline(v, 2.0 + 2.0 - 0.1, 0.0, math.pi)  # front to front: 2 + 2 m from CG to CG, less 0.1
    assert sat_overlap(a, b) == pytest.approx(0.1, abs=1e-3)  # (64 corners: faceted by ~0.01 mm)


def test_crush_bound_from_campbells_side_line():
    """A car at 15.6 m/s into a barrier may keep (15.6 - 0.9) / 20.33 = 0.72 m of crush; two cars closing at
    20 m/s twice (20 - 0.9) / 20.33 = 1.88 m; a car at 0.5 m/s none."""
    from types import SimpleNamespace
    a, b = SimpleNamespace(name="A"), SimpleNamespace(name="B")
    t = np.zeros(3)
    out = SimpleNamespace(trajectories={"A": {"vx": t + [0, 15.6, 3], "vy": t}, "B": {"vx": t - [0, 4.4, 0], "vy": t}})
    assert crush_bound(out, a) == pytest.approx(14.7 / 20.333, rel=1e-3)
    assert crush_bound(out, a, b) == pytest.approx(2 * 19.1 / 20.333, rel=1e-3)
    out.trajectories["A"]["vx"] = t + 0.5
    assert crush_bound(out, a) == 0.0



def test_an_elastic_release_is_told_from_a_gain():
    """A 3D vehicle's rigid-body energy rising 7 kJ while its recorded mechanical energy (springs included) falls
    is the springs giving back (`_elastic_release`); the same rise with the recorded energy rising 3 kJ, over the
    2.5 kJ tolerance, is a gain; without the column the rise is a gain."""
    t = np.linspace(0.0, 0.2, 21)
    rigid_rise = np.linspace(0.0, 7e3, 21)
    assert _elastic_release({"t": t, "energy": 16e3 - rigid_rise / 7}, t, 2.5e3)
    assert not _elastic_release({"t": t, "energy": 14e3 + rigid_rise * 3 / 7}, t, 2.5e3)
    assert not _elastic_release({"t": t}, t, 2.5e3)

def test_audit_catches_broken_outcomes():
    """The audit finds an energy gain in free motion, an overlap at rest, NaN, a false at-rest, and an impact
    that creates energy, in an Outcome doctored after the guard (the guard is not asked)."""
    scene = audit_scene(0)
    out = crashlab.get_model("impulse").simulate(scene)
    assert audit(scene, out, False) == [] or not out.outcome_ok
    name = scene.vehicles[0].name
    tr = out.trajectories[name]
    boosted = {k: np.array(a, dtype=float) for k, a in tr.items()}
    k = len(boosted["t"]) // 2
    boosted["vx"][k:] += 5.0 * np.sign(boosted["vx"][k:] + 1e-9)  # +5 m/s from mid-run, kept to the end
    out2 = _copy(out, trajectories={**out.trajectories, name: boosted})
    out2.final_si[0, 0] = boosted["vx"][-1]
    assert any(f.startswith(("energy_free", "energy_end")) for f in audit(scene, out2, False))
    out3 = _copy(out)
    out3.rest_si[1] = out3.rest_si[0]  # two cars on one spot
    assert any(f.startswith("overlap") for f in audit(scene, out3, False))
    out4 = _copy(out)
    out4.rest_si[0, 0] = math.nan
    assert audit(scene, out4, False) == ["non_finite: end state"]
    out5 = _copy(out)
    out5.final_si[0] = (3.0, 0.0, 0.0)  # moving, trajectory says otherwise
    assert any(f.startswith("end_state") for f in audit(scene, out5, False))
    if out.impact_rows:
        out6 = _copy(out, impact_rows=[dict(out.impact_rows[0], energy=-50e3)])
        assert any(f.startswith("impact_energy") for f in audit(scene, out6, False))


def _copy(out, trajectories=None, impact_rows=None):
    from crashlab.outcome import Outcome
    return Outcome(out.names, out.rest_si.copy(), out.final_si.copy(), trajectories=trajectories or out.trajectories,
                   impact_rows=out.impact_rows if impact_rows is None else impact_rows, model=out.model)


class _Doctored:
    """A stand-in model (no CollisionModel, so no guard): the impulse model's Outcome changed by `edit`."""

    def __init__(self, edit):
        self.inner, self.edit = crashlab.get_model("impulse"), edit

    def simulate(self, scene):
        out = self.inner.simulate(scene)
        self.edit(out)
        return out


def _gain(out):  # +8 m/s on V1 from mid-run (trajectory and end state): energy from nowhere
    tr = out.trajectories[out.names[0]]
    k = len(tr["t"]) // 2
    tr["vx"] = np.asarray(tr["vx"], dtype=float).copy()
    tr["vx"][k:] += 8.0
    out.final_si[0, 0] = tr["vx"][-1]


def _silent_fail(out):
    out.outcome_ok, out.warnings = False, []


def _false_alarm(out):
    out.fail("energy_overall", "a verdict with nothing behind it")


@pytest.mark.parametrize("edit, expected", [(_gain, "silent"), (_silent_fail, "no_reason"),
                                            (_false_alarm, "false_alarm?"), (lambda out: None, "ok")])
def test_classify_tells_the_classes_apart(edit, expected):
    """The classification is not blind: an energy gain the guard did not see is "silent", a failure without a
    reason "no_reason", a guard verdict on clean physics "false_alarm?" (scene 1 passes both as it is)."""
    cls, cause, found = classify(audit_scene(1), _Doctored(edit), rounded=False)
    assert cls == expected, (cls, cause, found)


def test_scenes_meet_the_brief():
    """3-5 vehicles, no overlap at the start, and across 40 seeds: actions, zones and barriers all occur."""
    from crashlab.scene import start_overlaps
    scenes = [audit_scene(s) for s in range(40)]
    assert all(3 <= len(s.vehicles) <= 5 and not start_overlaps(s) for s in scenes)
    assert sum(any(v.actions for v in s.vehicles) for s in scenes) > 10
    assert sum(bool(s.road.zones) for s in scenes) > 10
    assert sum(bool(s.barriers) for s in scenes) > 5


# ------------------------------------------------------------------ the audit
def test_audit_impulse_few():
    """Default run: 8 impulse scenes, no silent violation, no failure without a reason."""
    counts, notes, worst = run_audit("impulse", range(8))
    _print_table("impulse", counts, notes, 0.0, worst)
    _assert_clean(counts)
    assert not any(cls == "false_alarm?" for _, cls, _, _ in notes), notes


# runs the audit disputes (model -> reason: a strict xfail), none open. Closed: multibody seed 28, a Clio shoved
# under the 18 t bus by a van at 24 m/s (the bus's contact body spanned z 0.61-1.69 m, the Clio's 0.08-0.58 m: it
# ended 1.64 m into the bus's plan shadow, beyond the audit's bound 1.41 m); the bus's body now reaches down to its
# published 320 mm (models/common/vehicle_3d.py chassis_shape, docs/physics.md §10 "Chassis bodies"), seed 28 ok
DISPUTED: dict[str, str] = {}


@pytest.mark.slow
@pytest.mark.parametrize("model_name", [pytest.param(m, marks=pytest.mark.xfail(strict=True, reason=DISPUTED[m]))
                                        if m in DISPUTED else m for m in COUNTS])
def test_guard_audit(model_name):
    """Issue 27's audit: COUNTS[model] random scenes; 0 silent violations, 0 failures without a reason,
    0 false alarms; exudyn fails fewer than 2 of 12."""
    t0 = time.perf_counter()
    counts, notes, worst = run_audit(model_name, range(COUNTS[model_name]))
    _print_table(model_name, counts, notes, time.perf_counter() - t0, worst)
    _assert_clean(counts)
    assert not any(cls == "false_alarm?" for _, cls, _, _ in notes), notes
    if model_name == "exudyn":
        assert sum(n for k, n in counts.items() if k != "ok") < 2, counts
