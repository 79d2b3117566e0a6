"""The physics guard: every Outcome of every model is checked against physics before anyone reads it.

A model's result that breaks physics is a failure with a reason, never a quiet number. The guard runs on
the Outcome of every `CollisionModel.simulate` / `simulate_batch` (the base class applies it, so built-in
and third-party models are checked alike, also a simulate assigned to an instance; crashlab.model). A
model may declare in `guard_skip` the checks that do not apply to it. Checks (docs/physics.md, "Physics guard"):

  energy_overall          the kinetic energy at the end exceeds the kinetic energy at the start
  energy_outside_contact  a vehicle's mechanical energy (the trajectory's column energy where a model
                          records it, else planar kinetic energy, m g z and 1/2 m vz^2 where the
                          trajectory records z and vz) rises while that vehicle touches no other vehicle
                          and no barrier (runs that record trajectories: batch runs of the impulse model
                          record none and get the end-to-start balance only)
  impact_energy           an impact creates energy (dissipated energy below zero)
  interpenetration        two vehicles, or a vehicle and a barrier, end with their outlines overlapping
  below_road              a part of a 3D vehicle's body lies below the road (trajectory column z_min): deeper
                          than ROAD_TOL_DEEP at any sample, or than ROAD_TOL on average over ROAD_SUSTAINED_S
and, always (no model skips them):
  non_finite              NaN or inf in the end state, in any column of a recorded trajectory, or in an
                          impact row's numbers (rows checked where built: every run that records
                          trajectories; a batch's rows, built on first access, are not built for it)
  end_state               the end state (rest poses, final velocities) contradicts the trajectory's last
                          sample by more than END_POSE_TOL / END_HEADING_TOL / END_VELOCITY_TOL /
                          END_YAW_RATE_TOL

Every Outcome is checked each time a model returns it, also one that was checked before (a plugin may
return an inner model's checked Outcome after changing it); checking again adds nothing to one that
passed unchanged.

Tolerance of the energy checks: ENERGY_TOL_J + ENERGY_TOL_REL x the kinetic energy at the start, per
vehicle for energy_outside_contact x the largest energy that vehicle had (a 3D vehicle's suspension and
body motions hold energy the planar balance does not see: a 5 cm heave of a 1,000 kg car is 0.5 kJ).
A vehicle that ends with |roll| or |pitch| above 90 deg is reported as rolled over (a warning and
`outcome.rolled_over`), not failed: that is what happened to it. docs/physics.md §19.
"""
from __future__ import annotations

import math

import numpy as np

from .scene import barrier_outline, vehicle_outline
from .units import G

CHECKS = ("energy_overall", "energy_outside_contact", "impact_energy", "interpenetration", "below_road")
# always on (a model cannot skip them): non_finite (NaN or inf in the end state or a trajectory) and end_state
# (the end state contradicts the trajectory's last sample)
ENERGY_TOL_J = 1000.0  # J
ENERGY_TOL_REL = 0.02  # of the kinetic energy at the start
PENETRATION_TOL = 0.05  # m of outline overlap left at the end
# below the road (docs/physics.md §19): the road contact (models/common/road_contact.py) carries a body's weight at
# 5 mm, and a body landing from a roll bounces off it within some 10-40 ms, as deep as its landing speed drives it
# (5 cm at 6 m/s); ROAD_TOL_DEEP is its depth at a landing at about 15 m/s (a fall from 11 m): a body deeper is
# passing through the road; one whose depth below the road averages more than ROAD_TOL over ROAD_SUSTAINED_S (far
# longer than a bounce) is not carried by it
ROAD_TOL = 0.05  # m
ROAD_TOL_DEEP = 0.10  # m
ROAD_SUSTAINED_S = 0.1  # s
CONTACT_PAD = 1e-3  # s: a sample this close to a contact belongs to it (a model's clock and its records differ
#                     by round-off, e.g. a contact at 0.24000000000000002 s against a sample at 0.2399999)
ROLLOVER_ANGLE = math.pi / 2  # rad of roll or pitch at the end
# the end state against the trajectory's last sample (docs/physics.md, "Physics guard"): a model may end its
# run up to one record interval after its last sample (0.01 s in the built-in models); within it a car moves
# at most v dt (70 m/s x 0.01 s = 0.7 m), its speed changes by at most the road's mu g dt (0.1 m/s), a contact
# aside; the tolerances are loose against that and tight against a contradiction (51 km/h against 0)
END_POSE_TOL = 1.0  # m
END_HEADING_TOL = 0.5  # rad
END_VELOCITY_TOL = 1.0  # m/s (3.6 km/h)
END_YAW_RATE_TOL = 1.0  # rad/s
_END_COLUMNS = ("x", "y", "heading", "vx", "vy", "yaw_rate")
_END_NAMES = ("x [m]", "y [m]", "heading [rad]", "vx [m/s]", "vy [m/s]", "yaw rate [rad/s]")


def check(scene, out, skip=frozenset()) -> None:
    """Run every check not in `skip` on `out` (in place): a violation calls out.fail(kind, reason)."""
    check_batch([scene], [out], skip)


def check_batch(scenes, outs, skip=frozenset()) -> None:
    """`check` over a batch; the energy balance and the end-state checks are vectorised (a reconstruction
    checks thousands of outcomes of one scene composition). Every Outcome is checked every time it is
    returned, also one checked before (`guarded` True: a plugin may have changed it since; issue 27):
    checking again adds nothing to an Outcome that passed and did not change."""
    todo = list(zip(scenes, outs))
    for _, o in todo:
        o.guarded = True
    groups: dict = {}
    for s, o in todo:  # one vectorised pass per vehicle count
        groups.setdefault(len(s.vehicles), []).append((s, o))
    for group in groups.values():
        _check_group(group, skip)


def _kinetic(mass, iz, v2, yaw_rate) -> np.ndarray:
    """Planar kinetic energy [J] summed over the vehicles (last axis): 1/2 m v^2 + 1/2 Iz r^2."""
    return (0.5 * mass * v2 + 0.5 * iz * np.square(yaw_rate)).sum(-1)


def _tolerance(e0):
    return ENERGY_TOL_J + ENERGY_TOL_REL * e0


def _check_group(group, skip) -> None:
    mass = np.array([[v.spec.mass for v in s.vehicles] for s, _ in group])
    iz = np.array([[v.spec.yaw_inertia for v in s.vehicles] for s, _ in group])
    start = np.array([[(v.speed, v.yaw_rate) for v in s.vehicles] for s, _ in group])
    final = np.stack([o.final_si for _, o in group])
    rest = np.stack([o.rest_si for _, o in group])
    e0 = _kinetic(mass, iz, start[..., 0] ** 2, start[..., 1])
    e1 = _kinetic(mass, iz, final[..., 0] ** 2 + final[..., 1] ** 2, final[..., 2])
    tol = _tolerance(e0)
    finite = np.isfinite(rest).all(axis=(1, 2)) & np.isfinite(final).all(axis=(1, 2))
    scene = group[0][0]
    same = all(len(s.barriers) == len(scene.barriers) for s, _ in group)
    near = _near_pairs(np.array([_radii(s) for s, _ in group]), np.array([_barrier_centres(s) for s, _ in group]),
                       rest) if same else np.ones(len(group), dtype=bool)
    for k, (scene, out) in enumerate(group):
        out.diagnostics.energy_start, out.diagnostics.energy_end = float(e0[k]), float(e1[k])
        if not out.outcome_ok:
            continue
        if not finite[k]:
            out.fail("non_finite", "the end state is not finite")
            continue
        if "energy_overall" not in skip and not e1[k] - e0[k] <= tol[k]:
            out.fail("energy_overall", _energy_reason(e0[k], e1[k], tol[k]))
        _check_one(scene, out, skip, float(tol[k]), near[k])


def _energy_reason(e0, e1, tol) -> str:
    return (f"kinetic energy {e1 / 1e3:.1f} kJ at the end, {e0 / 1e3:.1f} kJ at the start (+{(e1 - e0) / 1e3:.1f} kJ, "
            f"tolerance {tol / 1e3:.1f} kJ)")


def _impact_reason(k, e, tol) -> str:
    return f"impact {k + 1} creates {-e / 1e3:.1f} kJ (tolerance {tol / 1e3:.1f} kJ)"


def _radii(scene) -> list[float]:
    """Bounding-circle radius of each vehicle's and barrier's outline [m]."""
    return [math.hypot(max(v.spec.cg_to_front, v.spec.cg_to_rear), v.spec.width / 2) for v in scene.vehicles] \
        + [math.hypot(b.length, b.width) / 2 for b in scene.barriers]


def _barrier_centres(scene) -> np.ndarray:
    return np.array([(b.x, b.y) for b in scene.barriers], dtype=float).reshape(-1, 2)


def _near_pairs(radius, bar, rest) -> np.ndarray:
    """Per row: whether any two outlines' bounding circles meet at the end (vehicles and barriers).
    radius (n, nv + nb), bar (n, nb, 2) barrier centres, rest (n, nv, 3)."""
    centres = np.concatenate([rest[..., :2], bar], axis=1)
    nv = rest.shape[1]
    d = np.linalg.norm(centres[:, :nv, None, :] - centres[:, None, :, :], axis=-1)
    reach = radius[:, :nv, None] + radius[:, None, :]
    close = d < reach
    close[:, np.arange(nv), np.arange(nv)] = False
    return close.any(axis=(1, 2))


def check_population(scene, fs, values, pop, skip=frozenset()) -> None:
    """The guard on a population (crashlab.population) of variants of `scene` with the fields `fs`
    (crashlab.fields.Field) set to the rows of `values` (file units), vectorised, in place: a violation fails
    the row with the reason "physics guard: <kind>: ...". The energy at the start is computed here from the
    scene and the rows (never taken from the model); energy_start and energy_end are written. The checks of
    recorded trajectories (energy_outside_contact, below_road) need an Outcome's trajectories: a population
    has none (a batch of the impulse model records none either)."""
    from .fields import vehicle_columns
    cols = vehicle_columns(scene, fs, values, ("speed", "yaw_rate", "mass", "yaw_inertia"))
    mass, iz = cols["mass"], cols["yaw_inertia"]
    final, rest = pop.final, pop.rest
    e0 = _kinetic(mass, iz, cols["speed"] ** 2, cols["yaw_rate"])
    e1 = _kinetic(mass, iz, final[..., 0] ** 2 + final[..., 1] ** 2, final[..., 2])
    pop.energy_start[:], pop.energy_end[:] = e0, e1
    tol = _tolerance(e0)

    def fail(mask, kind, reason):
        for k in np.flatnonzero(mask & pop.ok):
            pop.fail(k, f"physics guard: {kind}: {reason(k)}")

    fail(~(np.isfinite(rest).all(axis=(1, 2)) & np.isfinite(final).all(axis=(1, 2))), "non_finite",
         lambda k: "the end state is not finite")
    if "energy_overall" not in skip:
        fail(~(e1 - e0 <= tol), "energy_overall", lambda k: _energy_reason(e0[k], e1[k], tol[k]))
    if "impact_energy" not in skip:
        low = pop.lowest_impact_energy
        fail((pop.n_impacts > 0) & ~(low >= -tol), "impact_energy",
             lambda k: f"an impact creates {-low[k] / 1e3:.1f} kJ (tolerance {tol[k] / 1e3:.1f} kJ)")
    if "interpenetration" not in skip:
        n = len(pop)
        near = _near_pairs(np.tile(_radii(scene), (n, 1)), np.tile(_barrier_centres(scene), (n, 1, 1)), rest)
        for k in np.flatnonzero(near & pop.ok):
            why = end_overlap(scene, rest[k])
            if why:
                pop.fail(k, f"physics guard: interpenetration: {why}")


def _check_one(scene, out, skip, tol, near) -> None:
    if "impact_energy" not in skip and (out._impact_energy is not None or out.impact_rows):
        e_imp = out.impact_energy.tolist()  # (a few impacts: Python beats numpy's reductions here)
        out.diagnostics.energy_impacts = math.fsum(e_imp)
        if not all(e >= -tol for e in e_imp):  # (a NaN fails too)
            k = int(np.argmin(e_imp))
            out.fail("impact_energy", _impact_reason(k, e_imp[k], tol))
    trajectories = out.trajectories
    if trajectories or not callable(out._impact_rows):  # (a batch's lazy rows stay unbuilt: see the docstring)
        _check_finite_impacts(out)
    if trajectories:
        _check_finite_trajectories(scene, out)
        _check_trajectory_end(scene, out)
        if "energy_outside_contact" not in skip:
            _check_free_energy(scene, out)
        if "below_road" not in skip:
            _check_road(scene, out)
        _report_rollover(scene, out)
    if "interpenetration" not in skip and near:
        _check_overlap(scene, out)


def _vehicle_contacts(out, name) -> np.ndarray:
    """(t_start, t_end) of the contacts of one vehicle with another vehicle or a barrier, from the impact
    rows (an impulse model's episode ends at t_end, a continuous contact lasts `duration`); a model
    without impact rows gives its contact_intervals for every vehicle. Road contact is no exemption: the
    road takes energy, it never gives any."""
    rows = out.impact_rows
    if not rows:
        return np.asarray(out.contact_intervals or [], dtype=float).reshape(-1, 2)
    iv = [(r["t"], r["t_end"] if "t_end" in r else r["t"] + r.get("duration", 0.0))
          for r in rows if r["vehicle"] == name]
    return np.asarray(iv, dtype=float).reshape(-1, 2)


def free_energy_rise(out, vehicle) -> tuple[float, float, float]:
    """(largest rise [J], its time [s], tolerance [J]) of one vehicle's energy within the stretches of its
    trajectory free of its own contacts; the tolerance is ENERGY_TOL_J + ENERGY_TOL_REL x the largest
    energy that vehicle had. `vehicle` is the scene's VehicleState."""
    tr = out.trajectories[vehicle.name]
    t = np.asarray(tr["t"])
    if "energy" in tr:  # the model's own full mechanical energy (3D: every body, every rotation)
        e = np.asarray(tr["energy"], dtype=float)
    else:
        m = vehicle.spec.mass
        e = 0.5 * m * (np.square(tr["vx"]) + np.square(tr["vy"])) \
            + 0.5 * vehicle.spec.yaw_inertia * np.square(tr["yaw_rate"])
        if "z" in tr:
            e = e + m * G * (np.asarray(tr["z"]) - tr["z"][0])
        if "vz" in tr:
            e = e + 0.5 * m * np.square(tr["vz"])
    tol = ENERGY_TOL_J + ENERGY_TOL_REL * float(np.max(np.abs(e)))
    if len(e) < 2 or float(np.ptp(e)) == 0.0:  # a constant energy (a parked car) rises nowhere
        return 0.0, math.nan, tol
    # step k joins samples k-1 and k; it is in contact when one of the vehicle's contacts touches it
    touched = np.zeros(len(t) - 1, dtype=bool)
    for c0, c1 in _vehicle_contacts(out, vehicle.name):
        touched |= (t[1:] >= c0 - CONTACT_PAD) & (t[:-1] <= c1 + CONTACT_PAD)
    worst, t_worst = 0.0, math.nan
    # a touched step starts a new free stretch at its end sample; within a stretch the rise at sample k is
    # e[k] minus the lowest energy since the stretch began
    starts = np.concatenate(([0], np.flatnonzero(touched) + 1))
    for s, end in zip(starts, np.append(starts[1:], len(t))):
        if end - s < 2:
            continue
        seg = e[s:end]
        rise = seg[1:] - np.minimum.accumulate(seg)[:-1]
        rise[_transient(rise, tol)] = 0.0
        j = int(np.argmax(rise))
        if rise[j] > worst:
            worst, t_worst = float(rise[j]), float(t[s + 1 + j])
    return worst, t_worst, tol


def _transient(rise, tol) -> np.ndarray:
    """The samples of a free stretch whose rise above the stretch's lowest energy so far exceeds `tol` alone: both
    neighbouring samples within it (the next one recorded). A one-sample transient that returns is the work of a
    step change of a driver's input on the bodies it moves (exudyn's knuckles and wheels turned by a steer that
    jumps: a parked Clio steered 15 deg in one step reads +1.6 kJ for one sample, +54 J the next), no gain of the
    vehicle's energy: a gain stays (the road takes at most mu m g |v| per second of it). docs/physics.md §19."""
    over = rise > tol
    before = np.concatenate(([False], over[:-1]))
    after = np.concatenate((over[1:], [True]))  # the last sample: no next one to show that it returns
    return over & ~before & ~after


def _check_free_energy(scene, out) -> None:
    for v, _ in _recorded(scene, out, "t"):
        if len(out.trajectories[v.name]["t"]) < 2:
            continue
        worst, t_worst, tol = free_energy_rise(out, v)
        if worst > tol:
            out.fail("energy_outside_contact", f"{v.name} gains {worst / 1e3:.1f} kJ without contact "
                     f"(by t = {t_worst:.2f} s; tolerance {tol / 1e3:.1f} kJ)")
            return


def _recorded(scene, out, column):
    """(vehicle, its trajectory) for the vehicles whose trajectory records `column`."""
    for v in scene.vehicles:
        tr = out.trajectories.get(v.name)
        if tr is not None and column in tr and len(tr[column]):
            yield v, tr


def _check_finite_trajectories(scene, out) -> None:
    """NaN or inf anywhere in a recorded trajectory fails (every comparison with NaN is False: the other
    checks would pass it quietly): the vehicle, the column and the time of the first such sample."""
    for v in scene.vehicles:
        tr = out.trajectories.get(v.name)
        for column, values in (tr or {}).items():
            a = np.asarray(values, dtype=float)
            if not np.isfinite(a).all():
                k = int(np.flatnonzero(~np.isfinite(a))[0])
                t = np.asarray(tr.get("t", ()), dtype=float)
                when = f"t = {t[k]:.3f} s" if k < len(t) and math.isfinite(t[k]) else f"sample {k}"
                out.fail("non_finite", f"{v.name}'s trajectory column {column} is {a[k]} at {when}")
                return


def _check_finite_impacts(out) -> None:
    """NaN or inf in a number of an impact row fails (non_finite), naming the row, its vehicle and column."""
    for k, row in enumerate(out.impact_rows):
        for column, value in row.items():
            if isinstance(value, float) and not math.isfinite(value):
                out.fail("non_finite", f"impact row {k + 1} ({row.get('vehicle')} with {row.get('other')}): "
                         f"column {column} is {value}")
                return


def _check_trajectory_end(scene, out) -> None:
    """The end state (rest_si, final_si) is the trajectory's last sample, within END_POSE_TOL and
    END_VELOCITY_TOL (a model may stop between two samples; docs/physics.md, "Physics guard")."""
    for i, v in enumerate(scene.vehicles):
        tr = out.trajectories.get(v.name)
        if tr is None or not all(k in tr and len(tr[k]) for k in _END_COLUMNS):
            continue
        end = np.array([float(tr[k][-1]) for k in _END_COLUMNS])
        state = np.concatenate((out.rest_si[i], out.final_si[i]))
        gap = np.abs(end - state)
        tol = np.array([END_POSE_TOL, END_POSE_TOL, END_HEADING_TOL, END_VELOCITY_TOL, END_VELOCITY_TOL,
                        END_YAW_RATE_TOL])
        bad = np.flatnonzero(~(gap <= tol))  # (NaN fails)
        if len(bad):
            k = int(bad[0])
            out.fail("end_state", f"{v.name}'s {_END_NAMES[k]} at the end is {state[k]:.3g}, its trajectory ends at "
                     f"{end[k]:.3g} (t = {float(tr['t'][-1]):.3f} s; tolerance {tol[k]:.3g})")
            return


def _check_road(scene, out) -> None:
    for v, tr in _recorded(scene, out, "z_min"):
        z = np.asarray(tr["z_min"], dtype=float)
        if np.isnan(z).all():
            continue
        t = np.asarray(tr["t"], dtype=float)
        k = int(np.nanargmin(z))  # (one NaN sample hides nothing: it fails non_finite, the rest is still read)
        if z[k] < -ROAD_TOL_DEEP:
            out.fail("below_road", f"{v.name} reaches {-z[k]:.2f} m below the road at t = {t[k]:.2f} s")
            return
        mean = _mean_depth(t, np.nan_to_num(np.maximum(-z, 0.0)), ROAD_SUSTAINED_S)
        if len(mean) and mean.max() > ROAD_TOL:
            k = int(np.argmax(mean))
            out.fail("below_road", f"{v.name}'s lowest point is {mean[k]:.2f} m below the road on average over "
                     f"{ROAD_SUSTAINED_S:g} s from t = {t[k]:.2f} s (the road carries a body at {ROAD_TOL:g} m; a "
                     "landing bounces off it)")
            return


def _mean_depth(t, depth, window) -> np.ndarray:
    """The time average of depth (piecewise linear between the samples t) over [t_k, t_k + window], for every
    sample k whose window ends within the record."""
    area = np.concatenate([[0.0], np.cumsum(np.diff(t) * (depth[1:] + depth[:-1]) / 2.0)])
    ends = t + window
    full = ends <= t[-1] + 1e-9
    if not full.any():
        return np.empty(0)
    i = np.minimum(np.searchsorted(t, ends[full], side="right") - 1, len(t) - 2)  # the segment each window ends in
    frac = (ends[full] - t[i]) / np.where(t[i + 1] > t[i], t[i + 1] - t[i], 1.0)
    d_end = depth[i] + frac * (depth[i + 1] - depth[i])
    area_end = area[i] + (ends[full] - t[i]) * (depth[i] + d_end) / 2.0
    return (area_end - area[full]) / window


def _report_rollover(scene, out) -> None:
    for v, tr in _recorded(scene, out, "roll"):
        roll, pitch = float(tr["roll"][-1]), float(tr.get("pitch", [0.0])[-1])
        # continuous angles: the attitude is upside down or on a side when the wrapped angle exceeds 90 deg
        roll_w, pitch_w = math.remainder(roll, 2 * math.pi), math.remainder(pitch, 2 * math.pi)
        if (abs(roll_w) > ROLLOVER_ANGLE or abs(pitch_w) > ROLLOVER_ANGLE) and v.name not in out.rolled_over:
            out.rolled_over.append(v.name)  # (once: the guard may check an Outcome again)
            out.warnings.append(f"{v.name} rolled over (ends at roll {math.degrees(roll_w):.0f} deg, "
                                f"pitch {math.degrees(pitch_w):.0f} deg)")


def _check_overlap(scene, out) -> None:
    why = end_overlap(scene, out.rest_si)
    if why:
        out.fail("interpenetration", why)


def end_overlap(scene, rest) -> str | None:
    """Why the outlines at the end pose rest (nv, 3: x, y, heading) overlap by more than PENETRATION_TOL
    (bounding circles first), or None."""
    from .geometry import penetration  # numba's import only when outlines meet
    shapes = []
    for v, (x, y, h) in zip(scene.vehicles, rest):
        s = v.spec
        shapes.append((v.name, x, y, math.hypot(max(s.cg_to_front, s.cg_to_rear), s.width / 2),
                       lambda v=v, x=x, y=y, h=h: vehicle_outline(v, x, y, h)))
    others = [(f"barrier {k}", b.x, b.y, math.hypot(b.length, b.width) / 2, lambda b=b: barrier_outline(b))
              for k, b in enumerate(scene.barriers)]
    for i, (ni, xi, yi, ri, oi) in enumerate(shapes):
        for nj, xj, yj, rj, oj in shapes[i + 1:] + others:
            if math.hypot(xi - xj, yi - yj) >= ri + rj:
                continue
            depth = penetration(oi(), oj())[0]
            if depth > PENETRATION_TOL:
                return f"{ni} and {nj} end overlapping by {depth:.2f} m"
    return None
