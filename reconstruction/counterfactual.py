"""Would it have been avoided? Counterfactuals answered from the posterior's draws (issue 28).

A `[[counterfactuals]]` table of a study names a change of the scene:

    [[counterfactuals]]
    name = "V1 at the limit"
    set = { "vehicles.V1.speed" = 50.0 }          # a field set to a value (file units)
    shift = { "vehicles.V1.actions.0.t" = -0.5 }  # a value added (the driver braking 0.5 s earlier)
    scale = { "vehicles.V2.speed" = 0.0 }         # a value multiplied
    keep = "position"                             # or "arrival"

Fields are crashlab.fields paths. Every kept draw of the posterior (or a random subsample of at most
`MAX_DRAWS`, `subsample`) is simulated again with the change, as one population (CollisionModel.simulate_population);
the answer: the probability that the vehicles do not touch (with its 90 % interval, Jeffreys' beta interval
of a binomial share), where they still touch each vehicle's speed at impact and delta-V at 5/50/95 %, and
where they do not (at most MISS_DRAWS such draws, a seeded random subsample, run again with trajectories) how far
apart the outlines stay and the time gap at the point where the CG paths cross, at 5/50/95 % (`miss`).

keep (docs/physics.md, "Counterfactuals"): "position" (default) keeps each vehicle's start as drawn: the
changed car starts where it was when the run starts (the moment the hazard appeared, for a scene that starts
there), the usual avoidance question ("had V1 driven at 50 km/h up to that point"). "arrival" moves a car
whose speed changed back or forth along its heading so that it would reach its first-contact point of the
draw at the same time, assuming it runs at constant speed from its start to that point: start + (v - v') t_c
along the heading (v, v' the drawn and changed speed, t_c the draw's first contact); a draw without contact
keeps its start.
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from crashlab import fields
from crashlab.errors import InputError
from crashlab.units import frame_in, ms_to_kmh, unit_in, value_in

MAX_DRAWS = 2000  # draws re-simulated per counterfactual (a random subsample of the kept ones beyond this)
MISS_DRAWS = 200  # draws without contact run again with trajectories for the miss distance and time gap
GRID_DT = 0.01  # s: the common time grid on which the outlines are compared (linear between recorded samples)
CROSSING_STRIDE = 5  # grid steps between the path samples searched for the crossing point
QUANTILES = (0.05, 0.5, 0.95)
# the units of counterfactuals.csv's columns (crashlab.units, shown units; the rest are counts and shares)
ROW_UNITS = {"<vehicle>.impact_speed_<q>": "km/h", "<vehicle>.delta_v_<q>": "km/h", "miss_distance_<q>": "m",
             "time_gap_<q>": "s"}


class CounterfactualFile(BaseModel):
    """A `[[counterfactuals]]` table (module docstring)."""
    model_config = ConfigDict(extra="forbid", populate_by_name=True)
    name: str = Field(min_length=1, max_length=200, description="label of the counterfactual in the outputs")
    set_: dict[str, float] = Field(default_factory=dict, alias="set",
                                   description="field path -> the value it is set to (file units)")
    shift: dict[str, float] = Field(default_factory=dict, description="field path -> the value added (file units)")
    scale: dict[str, float] = Field(default_factory=dict, description="field path -> the factor it is multiplied by")
    keep: Literal["position", "arrival"] = Field(
        default="position", description="\"position\": the starts as drawn; \"arrival\": a car whose speed "
        "changed starts where it reaches its drawn first-contact point at the same time")


@dataclasses.dataclass(frozen=True)
class Counterfactual:
    name: str
    changes: tuple  # (how, crashlab.fields.Field, value): how in "set", "shift", "scale"
    keep: str


def parse(raw, scene, path) -> list[Counterfactual]:
    """The study's [[counterfactuals]] checked against the scene; InputError naming the key."""
    from crashlab.input_files import pydantic_error
    if not isinstance(raw, list):
        raise InputError(path, "counterfactuals", "a list of tables ([[counterfactuals]] name = ..., set = {...})")
    out = []
    seen = {"posterior": None}  # name -> its table's index; "posterior": the row of the draws as they are
    for k, entry in enumerate(raw):
        key = f"counterfactuals.{k}"
        try:
            cf = CounterfactualFile.model_validate(entry)
        except ValidationError as err:
            raise pydantic_error(path, err, key + ".", CounterfactualFile) from None
        if cf.name in seen:
            raise InputError(path, f"{key}.name", f"duplicate counterfactual name {cf.name!r} " + (
                f"(counterfactuals.{seen[cf.name]})" if seen[cf.name] is not None else
                "(the name of the draws as they are in the outputs)"))
        seen[cf.name] = k
        changes = []
        for how, table in (("set", cf.set_), ("shift", cf.shift), ("scale", cf.scale)):
            for p, value in table.items():
                where = f"{key}.{how}.{p}"
                try:
                    f = fields.resolve(scene, p)
                except ValueError as err:
                    raise InputError(path, where, str(err)) from None
                if not math.isfinite(value):
                    raise InputError(path, where, f"a finite number, got {value}")
                if how == "set":
                    lo, hi = fields.field_range(scene, f)
                    if not lo <= value <= hi:
                        raise InputError(path, where, f"{value:g} is outside [{lo:g}, {hi:g}] {f.unit}")
                changes.append((how, f, float(value)))
        if not changes:
            raise InputError(path, key, "a counterfactual changes something: give set, shift or scale")
        if len({f.path for _, f, _ in changes}) < len(changes):
            raise InputError(path, key, "a field changed twice")
        made = Counterfactual(cf.name, tuple(changes), cf.keep)
        _check_start_apart(made, scene, path, key)
        out.append(made)
    return out


def _check_start_apart(cf: Counterfactual, scene, path, key) -> None:
    """InputError naming the change when the counterfactual, applied to the scene's own values, puts two
    outlines (or a vehicle and a barrier) into an overlap at the start that the scene does not have."""
    from crashlab.scene import start_overlaps
    fs, V = changed_values(cf, scene, [], np.zeros((1, 0)))
    # unchecked first: the checked setter refuses an overlap too, naming no change (crashlab.fields.setter)
    moved = fields.setter(scene, fs, check=False)(V[0])
    new = sorted(set(start_overlaps(moved)) - set(start_overlaps(scene)))
    if new:
        a, b = new[0]
        how, f, _ = next((c for c in cf.changes if getattr(c[1], "vehicle", None) in (a, b)), cf.changes[0])
        raise InputError(path, f"{key}.{how}.{f.path}", f"moves the start of {a} into an overlap with {b}; a "
                         "counterfactual changes what happened before the crash, not where the cars stood apart")
    try:
        fields.set_fields(scene, fs, V[0])
    except ValueError as err:  # a shift or scale taking a value out of its range
        raise InputError(path, key, str(err)) from None


def changed_values(cf: Counterfactual, scene, var_fields, X, contact_t=None) -> tuple[list, np.ndarray]:
    """(fields, values): the draws X (n, k) of var_fields with the counterfactual's changes applied; a changed
    field that is no variable gets a column of its scene value first. contact_t (n,) [s]: each draw's first
    contact (keep = "arrival")."""
    fs = list(var_fields)
    V = np.array(X, dtype=float, copy=True)

    def column(f):
        nonlocal V
        for c, g in enumerate(fs):
            if g.path == f.path:
                return c
        fs.append(f)
        V = np.column_stack([V, np.full(len(V), fields.get(scene, f))])
        return len(fs) - 1
    for how, f, value in cf.changes:
        c = column(f)
        before = V[:, c].copy()
        V[:, c] = value if how == "set" else (before + value if how == "shift" else before * value)
        if cf.keep == "arrival" and f.kind == "vehicle" and f.quantity == "speed":
            t = np.nan_to_num(np.asarray(contact_t, float), nan=0.0)  # no contact: the start kept
            ch, cx, cy = (column(fields.parse(f"vehicles.{f.vehicle}.{q}")) for q in ("heading", "x", "y"))
            h = np.radians(V[:, ch])
            back = (before - V[:, c]) / 3.6 * t  # m: (v - v') t_c
            V[:, cx] += back * np.cos(h)
            V[:, cy] += back * np.sin(h)
    return fs, V


# ---------------------------------------------------------------- how far apart they stay (docs/physics.md §29)
def tracks(outcome, dt: float = GRID_DT) -> tuple[np.ndarray, np.ndarray]:
    """(t (T,), poses (nv, T, 3)): each vehicle's CG x, y [m] and heading [rad] on one time grid of step dt,
    linear between the recorded samples (heading unwrapped first), the last pose held after a record ends.
    ValueError when the run recorded no trajectories."""
    trs = [(outcome.trajectories or {}).get(n) for n in outcome.names]
    if any(tr is None or not len(tr["t"]) for tr in trs):
        raise ValueError("the run recorded no trajectories")
    end = max(float(tr["t"][-1]) for tr in trs)
    t = np.arange(0.0, end + dt / 2, dt)
    poses = np.empty((len(trs), len(t), 3))
    for i, tr in enumerate(trs):
        tt = np.asarray(tr["t"], float)
        for j, (key, wrap) in enumerate((("x", False), ("y", False), ("heading", True))):
            v = np.asarray(tr[key], float)
            poses[i, :, j] = np.interp(t, tt, np.unwrap(v) if wrap else v)
    return t, poses


def outline_corners(spec, poses) -> np.ndarray:
    """(T, 4, 2) corners of a vehicle's outline (its spec's cg_to_front, cg_to_rear, width) at poses (T, 3),
    in the order of crashlab.geometry.rect_corners."""
    hw = spec.width / 2
    local = np.array([(spec.cg_to_front, -hw), (spec.cg_to_front, hw), (-spec.cg_to_rear, hw),
                      (-spec.cg_to_rear, -hw)])
    c, s = np.cos(poses[:, 2])[:, None], np.sin(poses[:, 2])[:, None]
    return np.stack([poses[:, :1] + c * local[:, 0] - s * local[:, 1],
                     poses[:, 1:2] + s * local[:, 0] + c * local[:, 1]], axis=-1)


def outline_distance(a, b) -> np.ndarray:
    """(T,) distance between two convex outlines (T, m, 2) that do not overlap: the smallest distance from a
    corner of one to an edge of the other (exact for disjoint convex polygons)."""
    def corners_to_edges(p, q):
        e0, d = q, np.roll(q, -1, axis=1) - q  # (T, m, 2) edge starts and vectors
        w = p[:, :, None, :] - e0[:, None, :, :]  # (T, corner, edge, 2)
        u = np.clip(np.einsum("tcek,tek->tce", w, d) / np.einsum("tek,tek->te", d, d)[:, None, :], 0.0, 1.0)
        return np.linalg.norm(w - u[..., None] * d[:, None, :, :], axis=-1).min(axis=(1, 2))
    return np.minimum(corners_to_edges(a, b), corners_to_edges(b, a))


def path_crossing(t, p, q) -> tuple[float, float]:
    """(t_p, t_q): the times two CG paths (T, 2), sampled at times t, pass the first point where they cross
    (the earliest on either path, linear between samples); (NaN, NaN) when they do not cross."""
    a, r = p[:-1], np.diff(p, axis=0)  # segments of p: a + u r, u in [0, 1]
    b, s = q[:-1], np.diff(q, axis=0)
    den = r[:, None, 0] * s[None, :, 1] - r[:, None, 1] * s[None, :, 0]
    w = b[None, :, :] - a[:, None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = (w[..., 0] * s[None, :, 1] - w[..., 1] * s[None, :, 0]) / den
        v = (w[..., 0] * r[:, None, 1] - w[..., 1] * r[:, None, 0]) / den
    hit = (den != 0) & (u >= 0) & (u <= 1) & (v >= 0) & (v <= 1)
    if not hit.any():
        return math.nan, math.nan
    dt = np.diff(t)
    i, j = np.nonzero(hit)
    tp, tq = t[i] + u[i, j] * dt[i], t[j] + v[i, j] * dt[j]
    k = int(np.argmin(np.minimum(tp, tq)))
    return float(tp[k]), float(tq[k])


def miss(scene, outcome) -> tuple[float, float]:
    """(distance [m], time gap [s]) of a run without contact (docs/physics.md §29): the smallest distance
    between the outlines of the nearest pair of vehicles over the run, and for that pair (i before j in the
    scene) t_j - t_i at the first point where their CG paths cross (positive: i passed it first; NaN when the
    paths do not cross, e.g. one stops short of the other's path)."""
    t, poses = tracks(outcome)
    specs = [v.spec for v in scene.vehicles]
    radius = [math.hypot(max(sp.cg_to_front, sp.cg_to_rear), sp.width / 2) for sp in specs]
    best = (math.inf, 0, 1)
    for i in range(len(specs)):
        for j in range(i + 1, len(specs)):
            # the outlines hold the CGs, so their distance lies in [d_cg - r_i - r_j, d_cg]: only the instants
            # whose CG distance is within r_i + r_j of the smallest can hold the smallest outline distance
            d_cg = np.hypot(*(poses[i, :, :2] - poses[j, :, :2]).T)
            near = d_cg <= d_cg.min() + radius[i] + radius[j]
            d = outline_distance(outline_corners(specs[i], poses[i, near]), outline_corners(specs[j], poses[j, near]))
            best = min(best, (float(d.min()), i, j))
    d, i, j = best
    stride = slice(None, None, CROSSING_STRIDE)  # the paths at 0.05 s: straight enough between samples
    ti, tj = path_crossing(t[stride], poses[i, stride, :2], poses[j, stride, :2])
    return d, tj - ti


def jeffreys_interval(k: int, n: int, level: float = 0.90) -> tuple[float, float]:
    """Jeffreys' interval of a binomial share k / n (Brown, Cai & DasGupta 2001): beta(k + 1/2, n - k + 1/2)
    quantiles; 0 and 1 at the ends."""
    from scipy.stats import beta
    if n == 0:
        return math.nan, math.nan
    a = (1.0 - level) / 2.0
    lo = 0.0 if k == 0 else float(beta.ppf(a, k + 0.5, n - k + 0.5))
    hi = 1.0 if k == n else float(beta.ppf(1.0 - a, k + 0.5, n - k + 0.5))
    return lo, hi


def subsample(X: np.ndarray, limit: int = MAX_DRAWS) -> np.ndarray:
    """X itself, or `limit` of its rows (elements) drawn at random without replacement, in their order, with a
    fixed seed (the same answer every run). Not an even stride: the draws of an ensemble sampler are walkers
    interleaved, and a stride sharing a factor with their number would pick the same few walkers."""
    if len(X) <= limit:
        return X
    return X[np.sort(np.random.default_rng(0).choice(len(X), limit, replace=False))]


@dataclasses.dataclass
class Answer:
    """One counterfactual (or the draws as they are) answered: the values simulated, the population, per draw
    the miss distance [m] and time gap [s] (NaN where they touch or the draw was not measured), the row."""
    name: str
    fields: list
    values: np.ndarray  # (n, k) file units
    pop: object  # crashlab.population.Population
    miss_distance: np.ndarray  # (n,)
    time_gap: np.ndarray  # (n,)
    row: dict


def answers(model, scene, var_fields, X, counterfactuals) -> list[Answer]:
    """The draws as they are (name "posterior", first) and each counterfactual (its rows: `_row`), with the
    populations and the per-draw miss distances (`miss`, on at most MISS_DRAWS draws that do not touch).
    model: a CollisionModel."""
    X = subsample(np.atleast_2d(np.asarray(X, dtype=float)))
    base = model.simulate_population(scene, var_fields, X, invalid="fail")
    out = [_answer("posterior", scene, list(var_fields), X, base)]
    for cf in counterfactuals:
        fs, V = changed_values(cf, scene, var_fields, X, _first_contact(base))
        out.append(_answer(cf.name, scene, fs, V, model.simulate_population(scene, fs, V, invalid="fail")))
    return out


def answer(model, scene, var_fields, X, counterfactuals) -> list[dict]:
    """One row per counterfactual (and the draws as they are, first: name "posterior"): draws, failed,
    p_avoided with its 90 % interval, per vehicle the speed at impact and delta-V [km/h] at 5/50/95 % where
    the vehicles still touch, the miss distance and time gap at 5/50/95 % where they do not. model: a
    CollisionModel."""
    return [a.row for a in answers(model, scene, var_fields, X, counterfactuals)]


def _first_contact(pop) -> np.ndarray:
    t = np.where(np.isfinite(pop.first_impact_t), pop.first_impact_t, np.inf).min(axis=1)
    return np.where(np.isfinite(t), t, np.nan)


def _answer(name, scene, fs, V, pop) -> Answer:
    n = len(pop)
    dist, gap = np.full(n, np.nan), np.full(n, np.nan)
    for k in subsample(np.flatnonzero(pop.ok & (pop.n_impacts == 0)), MISS_DRAWS):
        try:
            dist[k], gap[k] = miss(scene, pop.outcome(int(k)))
        except ValueError:  # a model that records no trajectories: not measured (miss_draws says how many were)
            break
    row = _row(name, scene, pop)
    reason = row.pop("failed_reason")
    row["miss_draws"] = int(np.isfinite(dist).sum())
    for what, values in (("miss_distance", dist), ("time_gap", gap)):
        ok = np.isfinite(values)
        q = np.quantile(values[ok], QUANTILES) if ok.any() else (math.nan,) * 3
        for p, val in zip(QUANTILES, q):
            row[f"{what}_{round(100 * p)}"] = float(val)
    row["failed_reason"] = reason
    return Answer(name, fs, V, pop, dist, gap, row)


def _row(name, scene, pop) -> dict:
    ok = pop.ok
    n = int(ok.sum())
    avoided = ok & (pop.n_impacts == 0)
    k = int(avoided.sum())
    lo, hi = jeffreys_interval(k, n)
    row = {"name": name, "draws": len(pop), "failed": len(pop) - n, "p_avoided": k / n if n else math.nan,
           "p_avoided_5": lo, "p_avoided_95": hi}
    hit = ok & (pop.n_impacts > 0)
    for i, v in enumerate(scene.vehicle_names):
        for what, values in (("impact_speed", pop.contact[hit, i, 3]), ("delta_v", pop.delta_v[hit, i])):
            q = np.quantile(ms_to_kmh(values), QUANTILES) if hit.any() else (math.nan,) * 3
            for p, val in zip(QUANTILES, q):
                row[f"{v}.{what}_{round(100 * p)}"] = float(val)
    reasons = [r for r in pop.reason[~ok] if r]
    row["failed_reason"] = max(set(reasons), key=reasons.count) if reasons else ""
    return row


def write_csv(rows, path, system: str = "si") -> None:
    """counterfactuals.csv: one row per counterfactual (`answer`'s rows), in US units with system "us"."""
    import pandas as pd
    frame_in(pd.DataFrame(rows), system, ROW_UNITS).to_csv(path, index=False)


def summary_lines(rows, system: str = "si") -> list[str]:
    """One line per row of `answer`, for the terminal and summary.md; speeds and distances in US units with
    system "us"."""
    out = []
    kmh, m = unit_in("km/h", system), unit_in("m", system)
    for r in rows:
        r = {k: value_in(v, "km/h", system) if k.endswith(".impact_speed_50") else
             value_in(v, "m", system) if k.startswith("miss_distance_") else v for k, v in r.items()}
        speeds = ", ".join(f"{k.split('.')[0]} {r[k]:.1f}" for k in r if k.endswith(".impact_speed_50")
                           and math.isfinite(r[k]))
        out.append(f"{r['name']}: avoided in {100 * r['p_avoided']:.1f} % of {r['draws'] - r['failed']} draws "
                   f"(90 % {100 * r['p_avoided_5']:.1f}-{100 * r['p_avoided_95']:.1f} %)"
                   + (f"; where they still touch, median impact speed {speeds} {kmh}" if speeds else "")
                   + (f"; where they do not, the outlines {r['miss_distance_50']:.2f} {m} apart at the closest "
                      f"(median; 5-95 % {r['miss_distance_5']:.2f}-{r['miss_distance_95']:.2f} {m})"
                      if math.isfinite(r.get("miss_distance_50", math.nan)) else "")
                   + (f", time gap at the crossing point {r['time_gap_50']:+.2f} s (5-95 % "
                      f"{r['time_gap_5']:+.2f} to {r['time_gap_95']:+.2f} s)"
                      if math.isfinite(r.get("time_gap_50", math.nan)) else "")
                   + (f"; {r['failed']} draws failed ({r['failed_reason']})" if r["failed"] else ""))
    return out


def posterior_draws(table, labels, path) -> np.ndarray:
    """(n, k) the draws of posterior.csv (table: as read, in file units) in the columns `labels`; InputError
    naming the file and the first column that is missing or holds a value that is no finite number (NaN, inf,
    text, blank: a corrupt posterior, never draws failing quietly), or "--out" when the table has no rows."""
    import pandas as pd
    if not len(table):
        raise InputError(path, "--out", "the posterior has no draws (a header without rows); run crashlab infer "
                         "STUDY --out DIR again")
    for lab in labels:
        if lab not in table.columns:
            raise InputError(path, lab, "a variable of the study is not in this posterior (another study?)")
        bad = ~np.isfinite(pd.to_numeric(table[lab], errors="coerce").to_numpy(float))
        if bad.any():
            r = int(np.flatnonzero(bad)[0])
            raise InputError(path, lab, f"a finite number in every row, got {_cell(table[lab].iloc[r])} in row {r + 1}")
    return table[list(labels)].to_numpy(float)


def _cell(value) -> str:
    """A cell of posterior.csv as the file gives it: a number (nan, inf too) as such, text quoted."""
    try:
        return f"{float(value):g}"
    except (TypeError, ValueError):
        return repr(value)


def run(post, samples, out_dir=None) -> list[Answer]:
    """The posterior's counterfactuals (post: a Posterior with counterfactuals) answered on its kept samples
    (file units, the posterior's variables as columns) with the study's model; with out_dir,
    counterfactuals.csv (one row per counterfactual, the draws as they are first, in the study's shown units:
    `crashlab avoid`, whose draws posterior_draws reads; `crashlab infer` writes it with its other outputs)."""
    from crashlab.execution import model_for
    spec = post.study.spec
    out = answers(model_for(spec.model, spec.model_options), post.study.scene, post.fields, samples,
                  post.counterfactuals)
    if out_dir is not None:
        write_csv([a.row for a in out], Path(out_dir) / "counterfactuals.csv", post.study.shown_units)
    return out
