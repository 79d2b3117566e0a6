"""A study's evidence: its [evidence] and [objective] tables read into an EvidenceSet, each item checked
(InputError names the key), a twin's values taken from the model's run of the base scene.

The evidence itself, its residuals and likelihood (and the contract they follow) are
crashlab.reconstruction.evidence_set; its names are importable from here too.
"""
from __future__ import annotations

import math

import numpy as np

from crashlab.units import ms_to_kmh

from .evidence_set import (
    UNITS,
    EvidenceItem,
    EvidenceSet,
    cg_path,
    crush_ees,
    delta_v,
    first_impact_point,
    log_likelihood_of,
    polyline_distance,
)


def _noise(rng, sigma):
    return 0.0 if rng is None else float(rng.normal(0.0, sigma))


def build_evidence(path, spec, names, twin_outcome=None, specs=None):
    """(EvidenceSet, rest dict name -> (x, y, heading deg or None), mode) from a study file's [evidence] and
    [objective]; twin_outcome: the model's run of the base scene (evidence.twin), which fills every value
    the file leaves out (module docstring of crashlab.reconstruction.study); specs: name -> VehicleSpec of the
    scene's vehicles (needed by damage evidence). InputError names the key."""
    from crashlab.errors import InputError
    ev = spec.evidence
    twin = ev.twin
    if ev.noise_seed is not None and not twin:
        raise InputError(path, "evidence.noise_seed", "noise is added to a twin's evidence only (twin = true)")
    rng = np.random.default_rng(ev.noise_seed) if ev.noise_seed is not None else None
    o = twin_outcome

    def check_name(name, key):
        if name not in names:
            raise InputError(path, key, f"no vehicle {name!r} in the scene ({', '.join(names)})")

    def given(value, key):
        """A measured value of a file that is no twin's."""
        if value is None:
            raise InputError(path, key, "missing key (or set evidence.twin = true to take it from the model's run)")
        return float(value)

    items: list[EvidenceItem] = []
    rest: dict = {}
    only_rest_twin = twin and not (ev.rest or ev.impact or ev.marks or ev.edr or ev.damage)
    if only_rest_twin:  # the thesis's twin: every vehicle's rest pose, as before
        for i, n in enumerate(names):
            rest[n] = (float(o.rest_si[i, 0]), float(o.rest_si[i, 1]), math.degrees(o.rest_si[i, 2]))
    mode = spec.objective.mode or ("misfit" if ev.has_uncertainty else "thesis")
    for n, p in ev.rest.items():
        key = f"evidence.rest.{n}"
        check_name(n, key)
        i = names.index(n)
        for k in ("x", "y", "heading"):
            if twin and getattr(p, k) is not None:
                raise InputError(path, f"{key}.{k}", "a twin's run gives this value: leave it out (or twin = false)")
        if twin:
            heading = math.degrees(o.rest_si[i, 2]) if (p.sigma_heading is not None or mode == "thesis") else None
            x, y = o.rest_si[i, 0] + _noise(rng, p.sigma_xy or 0.0), o.rest_si[i, 1] + _noise(rng, p.sigma_xy or 0.0)
            if heading is not None:
                heading += _noise(rng, p.sigma_heading or 0.0)
        else:
            x, y, heading = given(p.x, f"{key}.x"), given(p.y, f"{key}.y"), p.heading
        rest[n] = (float(x), float(y), heading)
        if mode == "misfit":
            if p.sigma_xy is None:
                raise InputError(path, f"{key}.sigma_xy", "missing key: the misfit objective needs every sigma")
            if heading is not None and p.sigma_heading is None:
                raise InputError(path, f"{key}.sigma_heading", "missing key: a heading needs its sigma")
            comps = ("x", "y", "heading") if heading is not None else ("x", "y")
            vals = (rest[n][0], rest[n][1], heading) if heading is not None else rest[n][:2]
            sig = (p.sigma_xy, p.sigma_xy, p.sigma_heading) if heading is not None else (p.sigma_xy,) * 2
            items.append(EvidenceItem("rest", f"rest.{n}", (n,), comps, tuple(map(float, vals)), tuple(sig)))
        elif p.sigma_heading is not None and heading is None:
            raise InputError(path, f"{key}.sigma_heading", "a sigma without its heading")
    if ev.impact is not None:
        p = ev.impact
        if twin:
            for k in ("x", "y"):
                if getattr(p, k) is not None:
                    raise InputError(path, f"evidence.impact.{k}", "a twin's run gives this value: leave it out")
            px, py = first_impact_point(o)
            if not math.isfinite(px):
                raise InputError(path, "evidence.impact", "the twin's run has no impact")
            vals = (px + _noise(rng, p.sigma), py + _noise(rng, p.sigma))
        else:
            vals = (given(p.x, "evidence.impact.x"), given(p.y, "evidence.impact.y"))
        items.append(EvidenceItem("impact", "impact", tuple(names), ("x", "y"), vals, (p.sigma, p.sigma)))
    for k, m in enumerate(ev.marks):
        key = f"evidence.marks.{k}"
        check_name(m.vehicle, f"{key}.vehicle")
        if m.points is not None:
            if m.n_points is not None:
                raise InputError(path, f"{key}.n_points", "give points or (twin) n_points, not both")
            pts = np.asarray(m.points, float)
        else:
            if not twin:
                raise InputError(path, f"{key}.points", "missing key: at least 2 points [x, y]")
            path_xy = cg_path(o, m.vehicle)
            if len(path_xy) < 2:
                raise InputError(path, f"{key}", "the twin's run recorded no CG path (model option record_dt)")
            idx = np.linspace(0, len(path_xy) - 1, m.n_points or 4).round().astype(int)
            pts = path_xy[idx] + (0.0 if rng is None else rng.normal(0.0, m.sigma, (len(idx), 2)))
        items.append(EvidenceItem("marks", f"marks.{k}", (m.vehicle,), tuple(f"p{j}" for j in range(len(pts))),
                                  tuple([0.0] * len(pts)), tuple([m.sigma] * len(pts)), pts))
    for n, e in ev.edr.items():
        key = f"evidence.edr.{n}"
        check_name(n, key)
        i = names.index(n)
        comps, vals, sig = [], [], []
        for c, s, sim in (("speed_at_impact", "sigma_speed", lambda i=i: ms_to_kmh(float(o.contact_si[i, 3]))),
                          ("delta_v", "sigma_delta_v", lambda n=n: ms_to_kmh(delta_v(o, n)))):
            value, sigma = getattr(e, c), getattr(e, s)
            if twin and value is not None:
                raise InputError(path, f"{key}.{c}", "a twin's run gives this value: leave it out (give its sigma)")
            if value is not None and sigma is None:
                raise InputError(path, f"{key}.{s}", f"missing key: {c} needs its sigma")
            if sigma is None:
                continue
            if twin:
                value = sim()
                if not math.isfinite(value):
                    raise InputError(path, key, "the twin's run has no contact")
                value = max(value + _noise(rng, sigma), 0.0)
            elif value is None:
                raise InputError(path, f"{key}.{c}", f"missing key: {s} is given without its value")
            comps.append(c)
            vals.append(float(value))
            sig.append(float(sigma))
        if not comps:
            raise InputError(path, key, "no value: give speed_at_impact and sigma_speed and/or delta_v and "
                             "sigma_delta_v")
        items.append(EvidenceItem("edr", f"edr.{n}", (n,), tuple(comps), tuple(vals), tuple(sig)))
    for n, e in ev.damage.items():
        items.append(_damage_item(path, n, e, names, (specs or {}).get(n), o if twin else None, rng))
    if mode == "thesis":
        if items:
            raise InputError(path, "objective.mode", "the thesis objective scores rest poses only: "
                             "use mode = \"misfit\" with this evidence")
        if not rest:
            raise InputError(path, "evidence.rest", "no measured rest pose given")
    else:
        if spec.objective.heading_weight:
            raise InputError(path, "objective.heading_weight", "the misfit objective weighs a heading by its "
                             "sigma_heading: give no heading_weight (or mode = \"thesis\")")
        if not items:
            raise InputError(path, "evidence", "no evidence with a sigma given")
    return EvidenceSet(names, items), rest, mode


def _damage_item(path, n, e, names, vspec, twin_outcome, rng) -> EvidenceItem:
    """The EvidenceItem of [evidence.damage.<n>] (its residual: crashlab.reconstruction.evidence_set). A twin's
    run fills the profile: a uniform 6-point profile whose EES is the run's (crashlab.damage.profile_for_ees),
    plus Gaussian noise sigma_crush on every depth (noise_seed; clipped at 0); the stiffness is the file's (its
    sigma is not drawn)."""
    from crashlab.damage import damage_ees_report, ees_is_upper_bound, profile_for_ees
    from crashlab.errors import InputError
    key = f"evidence.damage.{n}"
    if n not in names:
        raise InputError(path, key, f"no vehicle {n!r} in the scene ({', '.join(names)})")
    if twin_outcome is not None:
        if e.profile is not None:
            raise InputError(path, f"{key}.profile", "a twin's run gives this value: leave it out (or twin = false)")
        sim = ms_to_kmh(crush_ees(twin_outcome, n, vspec.mass, e.side))
        profile = np.array(profile_for_ees(sim if math.isfinite(sim) else 0.0, vspec, e.side, e.width, pdof=e.pdof,
                                           where=path, prefix=f"{key}."))  # (the evidence's own errors first)
        if not math.isfinite(sim):
            raise InputError(path, key, f"the twin's run has no impact of {n} on its {e.side}")
        if rng is not None:
            profile = np.maximum(profile + rng.normal(0.0, e.sigma_crush, len(profile)), 0.0)
        e = e.model_copy(update={"profile": [float(c) for c in profile]})
    value, sigma, rep = damage_ees_report(e, vspec, path, f"{key}.")
    bound = ees_is_upper_bound(rep["profile"], e.sigma_crush)
    if bound and max(rep["profile"]) > 0.0:  # (all zero: report's own warning says it)
        rep["warnings"].append(f"mean residual crush {sum(rep['profile']) / len(rep['profile']):.3f} m, within "
                               f"sigma_crush {e.sigma_crush:g} m of none: the measurement cannot tell this crush from "
                               "none, so the damage is scored one-sided, as the most the impact may have been (a "
                               "simulated EES above this profile's counts against a run, one below it does not; "
                               "docs/physics.md §28)")
    detail = (f"CRASH3, {rep['side']} crush {', '.join(f'{c:.3f}' for c in rep['profile'])} m over "
              f"{rep['width']:g} m, A {rep['A'] / 1e3:.1f} kN/m, B {rep['B'] / 1e3:.0f} kN/m^2, PDOF factor "
              f"{rep['pdof_factor']:.2f}; sigma from {e.sigma_crush:g} m per depth and {e.sigma_stiffness:.0%} "
              "stiffness" + "".join(f"; warning: {w}" for w in rep["warnings"]))
    return EvidenceItem("damage", f"damage.{n}", (n,), ("ees",), (float(value),), (float(sigma),),
                        mass=float(vspec.mass), side=e.side, detail=detail, warnings=tuple(rep["warnings"]),
                        upper_bound=bound)


__all__ = ["UNITS", "EvidenceItem", "EvidenceSet", "build_evidence", "cg_path", "crush_ees", "delta_v",
           "first_impact_point", "log_likelihood_of", "polyline_distance"]
