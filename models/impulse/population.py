"""The impulse model's populations: the base scene packed once, each variant's values written into the kernel's
arrays, one parallel compiled call, the results read back as arrays (crashlab.population). No Scene, no Outcome
and no Python loop per variant where the fields are start states, masses, yaw inertias, frictions or impact
numbers; other fields (a start steer, an action's time, brake or steer, which the action tables derive from)
pack one scene per variant, still without an Outcome.

The arrays are the ones `ImpulseModel.pack` makes of the changed scene, bit for bit
(tests/test_population.py), so a population gives exactly what simulate_batch gives.
"""
from __future__ import annotations

import math

import numpy as np

from crashlab.fields import setter, vehicle_columns
from crashlab.models.common.impact_rows import struck_compliance
from crashlab.models.common.planar_vehicle import P_IZ, P_MASS
from crashlab.outcome import at_rest
from crashlab.population import Population

from . import kernel as K
from . import layout as L
from .run_warnings import over_capacity, run_warnings, sustained

_STATE = ("x", "y", "heading", "speed", "yaw_rate")
_SETTING = {"restitution": "restitution", "friction": "impact_friction", "engagement_depth": "engagement_depth"}


def _direct(f) -> bool:
    """Whether the field's value goes straight into the packed arrays (else the variant's scene is packed)."""
    return (f.kind == "vehicle" and f.quantity in _STATE) or f.kind in ("spec", "road", "zone", "impact")


def pack_variants(model, scene, fs, values) -> tuple:
    """The kernel's stacked arrays (P, S0, B, cfg, A, NA, ZC, ZS, ZMU, ZBOX) of every variant."""
    n = len(values)
    if not all(_direct(f) for f in fs):
        build = setter(scene, fs, check=False)
        packs = [model.pack(build(row)) for row in values]
        return tuple(np.stack([p[k] for p in packs]) for k in range(6)) + \
            tuple(np.stack([p[6][k] for p in packs]) for k in range(4))
    P, S0, B, cfg, A, NA, zones = model.pack(scene)
    P, S0, B, cfg, A, NA = (np.repeat(np.asarray(a)[None], n, axis=0) for a in (P, S0, B, cfg, A, NA))
    ZC, ZS, ZMU, ZBOX = (np.repeat(a[None], n, axis=0) for a in zones)
    names = scene.vehicle_names
    cols = vehicle_columns(scene, fs, values, _STATE + ("mass", "yaw_inertia"))
    for f_i, f in enumerate(fs):
        v = f.to_si_array(values[:, f_i])
        if f.kind == "spec":
            P[:, names.index(f.vehicle), P_MASS if f.quantity == "mass" else P_IZ] = v
        elif f.kind == "road":
            cfg["road_friction"] = v
        elif f.kind == "zone":
            ZMU[:, f.index] = v
        elif f.kind == "impact":
            cfg[_SETTING[f.quantity]] = v  # a number given replaces restitution = "speed" (fields.setter)
    for i in {names.index(f.vehicle) for f in fs if f.kind == "vehicle"}:
        S0[:, i, 0], S0[:, i, 1], S0[:, i, 5] = cols["x"][:, i], cols["y"][:, i], cols["yaw_rate"][:, i]
        S0[:, i, 2] = cols["heading"][:, i]
        # the velocity as pack computes it (math.cos, math.sin: the same bits)
        heading = cols["heading"][:, i].tolist()
        S0[:, i, 3] = cols["speed"][:, i] * np.fromiter(map(math.cos, heading), float, len(heading))
        S0[:, i, 4] = cols["speed"][:, i] * np.fromiter(map(math.sin, heading), float, len(heading))
    return P, S0, B, cfg, A, NA, ZC, ZS, ZMU, ZBOX


def simulate_variants(model, scene, fs, values) -> Population:
    """The Population of the variants (CollisionModel.simulate_population's contract)."""
    arrays = pack_variants(model, scene, fs, values)
    n, nv = arrays[0].shape[0], arrays[0].shape[1]
    rest, final, contact = np.empty((n, nv, 3)), np.empty((n, nv, 3)), np.empty((n, nv, 4))
    # (the impact records beyond each run's count are never read: no zeroing of n x max_impacts rows)
    imp, diag = np.empty((n, model.impact_cap(nv), L.N_IMP)), np.zeros((n, L.N_DIAG))
    K.simulate_many(*arrays, rest, final, contact, imp, diag)
    pop = population_of(model, scene.vehicle_names, rest, final, contact, imp, diag,
                        struck_compliance(v.spec for v in scene.vehicles))
    _warnings(pop, scene, fs, arrays[0], arrays[3], imp, diag)
    return pop


def _warnings(pop, scene, fs, P, cfg, imp, diag) -> None:
    """pop.warnings of the runs that did not fail, as their Outcomes would carry them (model.run_warnings), built
    only for the runs whose records call for one (a vectorised screen: no Python per quiet run; a run whose only
    warnings are restitution = "speed" outside its data gets them straight from range_warning)."""
    from crashlab.restitution import SPEED, V_MAX, V_MIN, range_warning

    n_imp = diag[:, L.D_IMPACTS].astype(int)
    recs = imp[:, :max(int(n_imp.max(initial=0)), 1)]
    valid = np.arange(recs.shape[1])[None, :] < n_imp[:, None]
    # a variant with its own constant restitution (field impact.restitution) does not use the law
    speed_law = scene.impact.restitution_law == SPEED and \
        not any(getattr(f, "path", f) == "impact.restitution" for f in fs)
    other = n_imp == 0
    if scene.impact.law != "routh":
        other |= (valid & (recs[..., L.I_REVERSED] >= 0.5)).any(1)
    if scene.impact.engagement:
        other |= (valid & np.isin(recs[..., L.I_ENGAGE], (L.ENGAGE_AMBIGUOUS, L.ENGAGE_FALLBACK))).any(1)
    with np.errstate(invalid="ignore", over="ignore"):  # (unfilled rows hold any numbers; valid masks them)
        other |= (valid & (over_capacity(recs) | sustained(recs))).any(1)
    held = np.zeros(len(n_imp), bool)
    if speed_law:
        closing = np.abs(recs[..., L.I_CLOSING])
        held = (valid & ((closing < V_MIN) | (closing > V_MAX))).any(1)
        for k in np.flatnonzero(pop.ok & held & ~other):
            rows = recs[k, :n_imp[k]]
            closing = rows[:, L.I_CLOSING]  # (a push's or a re-impact's row has none: NaN)
            pop.warnings[k] = "\n".join(filter(None, map(range_warning, closing[np.isfinite(closing)].tolist())))
    for k in np.flatnonzero(pop.ok & other):
        pop.warnings[k] = "\n".join(run_warnings(scene, scene.vehicle_names, P[k, :, P_MASS], imp[k, :n_imp[k]],
                                                  speed_law, float(cfg["engagement_depth"][k])))


def population_of(model, names, rest, final, contact, imp, diag, compliance) -> Population:
    """The kernel's outputs of n runs as a Population (the columns the Outcome route reads from impact rows,
    models/common/impact_rows.py: crush energy split by the struck faces' compliance (nv, 6) and booked per struck
    face, a barrier takes none)."""
    n, nv = rest.shape[0], rest.shape[1]
    pop = Population.empty(n, names, "")
    status = diag[:, L.D_STATUS].astype(int)
    ok = status == L.STATUS_OK
    texts = model.status_text()
    pop.reason[~ok] = [texts[s] for s in status[~ok]]
    n_imp = diag[:, L.D_IMPACTS].astype(int)
    imp = imp[:, :max(int(n_imp.max(initial=0)), 1)]  # the records in use
    valid = np.arange(imp.shape[1])[None, :] < n_imp[:, None]  # (n, impacts)
    # impacts (contact episodes): a push row continues its impact's episode (§5)
    pop.ok[:], pop.n_impacts[:] = ok, (valid & (imp[..., L.I_KIND] != L.PUSH)).sum(1)  # (pop.mass: the wrapper's)
    good = np.flatnonzero(ok)
    pop.rest[good], pop.final[good], pop.contact[good] = rest[good], final[good], contact[good]
    pop.rest_speed[good] = np.hypot(final[good, :, 0], final[good, :, 1])
    pop.at_rest[good] = at_rest(final[good])
    imp = np.where(valid[..., None], imp, 0.0)  # (unwritten records)
    energy = imp[..., L.I_ENERGY]
    pop.energy_impacts[good] = energy.sum(1)[good]
    low = np.where(valid, imp[..., L.I_ENERGY], np.inf).min(1)
    pop.lowest_impact_energy[good] = np.where(np.isfinite(low), low, np.nan)[good]
    i, j = imp[..., L.I_I].astype(int), imp[..., L.I_J].astype(int)
    c_i = compliance[np.clip(i, 0, nv - 1), imp[..., L.I_SIDE_I].astype(int)]
    c_j = np.where(j < nv, compliance[np.clip(j, 0, nv - 1), imp[..., L.I_SIDE_J].astype(int)], 0.0)
    positive, both = np.maximum(energy, 0.0), c_i + c_j
    for v in range(nv):
        as_i, as_j = valid & (i == v), valid & (j == v)
        dvx = np.where(as_i, imp[..., L.I_DVX_I], 0.0) + np.where(as_j, imp[..., L.I_DVX_J], 0.0)
        dvy = np.where(as_i, imp[..., L.I_DVY_I], 0.0) + np.where(as_j, imp[..., L.I_DVY_J], 0.0)
        crush = np.where(as_i, positive * c_i / both, 0.0) + np.where(as_j, positive * c_j / both, 0.0)
        face = np.where(as_i, imp[..., L.I_SIDE_I], imp[..., L.I_SIDE_J])  # the face v is struck on
        pop.delta_v[good, v] = np.hypot(dvx.sum(1), dvy.sum(1))[good]
        for k in range(compliance.shape[1]):
            pop.crush_energy[good, v, k] = np.where(face == k, crush, 0.0).sum(1)[good]
        hit = as_i | as_j
        first = hit.argmax(1)
        some = hit.any(1)
        rows = np.arange(n)
        pick = good[some[good]]
        pop.first_delta_v[good, v] = 0.0
        pop.first_delta_v[pick, v] = np.hypot(dvx[rows, first], dvy[rows, first])[pick]
        pop.first_impact_t[pick, v] = imp[rows, first, L.I_T][pick]
        pop.first_impact_point[pick, v, 0] = imp[rows, first, L.I_PX][pick]
        pop.first_impact_point[pick, v, 1] = imp[rows, first, L.I_PY][pick]
    return pop
