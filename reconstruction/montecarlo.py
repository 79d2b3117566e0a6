"""Forward Monte Carlo: the scene's uncertain parameters drawn N times, every draw simulated, and where the
vehicles come to rest (and their delta-V) as distributions (docs/physics.md, uncertain parameters).

The draws are made at once (crashlab.uncertainty.sample, a seeded numpy Generator) and simulated as a
population of variants of the scene, in blocks (the model's `simulate_population`, crashlab.population: the
impulse model writes the draws into its compiled kernel's arrays and runs them in parallel). A draw fails,
and is counted and named, never dropped silently, when its scene cannot be built, the model's run fails
(the physics guard's verdict included), or a vehicle is still moving at the end of the run (its end pose is
no rest pose: lengthen the duration). Statistics are over the draws that did not fail; a draw whose vehicles
do not touch is no failure (delta-V 0).

delta_v of a vehicle is the change of its CG velocity in its first impact [km/h] (what an event data
recorder reports), 0 without contact. Headings are continuous (turns counted), as the model reports them.

The model's warnings of each draw (a law used outside its assumptions: restitution = "speed" held at its end
value outside the law's data, docs/physics.md §13b; a slip that reverses, §3; no contact) are kept from the
population (crashlab.population, column warnings) and told once per kind with the number of draws that gave
it (crashlab.warning_groups; numbers that differ between the draws as their range): warning_counts(),
print_summary, print_warnings (stderr), warnings.csv, the JSON; never one line per draw.
"""
from __future__ import annotations

import collections
import dataclasses
import math
import time
from pathlib import Path

import numpy as np

from crashlab import uncertainty
from crashlab.errors import InputError
from crashlab.execution import evaluate_variants
from crashlab.outcome import Outcome
from crashlab.population import Population, Variants
from crashlab.scene import Scene
from crashlab.units import frame_in, json_number, length_axes_in, ms_to_kmh, uncertain_text, unit_in, value_in

BATCH = 5000  # draws per simulate_population call (a block of the progress bar)
QUANTILES = (0.05, 0.5, 0.95)
PER_VEHICLE = ("x", "y", "heading", "delta_v", "ok")
SUMMARY_UNITS = {"x": "m", "y": "m", "heading": "deg", "delta_v": "km/h"}  # file units of summary()'s quantities


@dataclasses.dataclass
class MonteCarloResult:
    """table: one row per draw: draw, the sampled parameters (columns named by their field paths, file
    units), per vehicle `V.x`, `V.y` [m], `V.heading` [deg, continuous], `V.delta_v` [km/h], `V.ok` (at rest
    at the end of a run that did not fail), then `ok`, `no_contact` and `reason` of the draw, and `warnings`
    (the model's warnings of the draw, one a line; not in montecarlo.csv: warning_counts() tells them). nominal:
    the Outcome of the scene as written."""
    scene: Scene
    model: str
    seed: int | None
    table: object  # pandas DataFrame
    nominal: object  # Outcome
    wall_time_s: float
    sim_time_s: float
    _warning_counts: list | None = dataclasses.field(default=None, init=False, repr=False, compare=False)

    @property
    def names(self) -> list[str]:
        return self.scene.vehicle_names

    @property
    def fields(self) -> list[str]:
        return [e.field for e in self.scene.uncertain]

    @property
    def n(self) -> int:
        return len(self.table)

    @property
    def failed(self):
        return self.table[~self.table["ok"]]

    def failure_reasons(self) -> dict[str, int]:
        return dict(collections.Counter(self.failed["reason"]).most_common())

    def warning_counts(self) -> list[tuple[str, int]]:
        """Each kind of the model's warning in the draws once (numbers that differ between the draws as their
        range, crashlab.warning_groups) with the number of draws that gave it, in the order they first occur."""
        from crashlab.warning_groups import group
        if self._warning_counts is None:  # (the summary, the JSON, the files and stderr all tell them)
            self._warning_counts = [(text, len(draws)) for text, draws in
                                    group(w.split("\n") if w else () for w in self.table["warnings"])]
        return self._warning_counts

    def summary(self):
        """Per vehicle and quantity (x, y [m], heading [deg], delta_v [km/h]): the median and the 5 and 95 %
        quantiles over the draws that did not fail, and the number of those draws."""
        import pandas as pd
        ok = self.table[self.table["ok"]]
        rows = []
        for n in self.names:
            for q in ("x", "y", "heading", "delta_v"):
                vals = ok[f"{n}.{q}"].to_numpy()
                p5, p50, p95 = np.quantile(vals, QUANTILES) if len(vals) else (math.nan,) * 3
                rows.append({"vehicle": n, "quantity": q, "median": p50, "p5": p5, "p95": p95, "draws": len(vals)})
        return pd.DataFrame(rows)

    def table_units(self) -> dict:
        """The units map (crashlab.units, shown units) of the table of draws (montecarlo.csv)."""
        from crashlab import fields
        return {e.field: fields.parse(e.field).unit for e in self.scene.uncertain} | {
            "<vehicle>.x": "m", "<vehicle>.y": "m", "<vehicle>.heading": "deg", "<vehicle>.delta_v": "km/h"}

    def shown_summary(self, system: str = "si"):
        """summary() in `system`'s units, with the unit of each row (column "unit")."""
        s = self.summary()
        units = s["quantity"].map(SUMMARY_UNITS)
        for c in ("median", "p5", "p95"):
            s[c] = [value_in(v, u, system) for v, u in zip(s[c], units)]
        return s.assign(unit=[unit_in(u, system) for u in units])

    def to_json_dict(self, system: str = "si") -> dict:
        """The summary as JSON, every number in `system`'s units (each summary row says its unit)."""
        return {"scene": self.scene.name, "model": self.model, "draws": self.n, "seed": self.seed,
                "failed": int((~self.table["ok"]).sum()), "failure_reasons": self.failure_reasons(),
                "no_contact": int(self.table["no_contact"].sum()),
                "warnings": [{"warning": w, "draws": k} for w, k in self.warning_counts()],
                "nominal_warnings": [str(w) for w in self.nominal.warnings],
                "uncertain": [uncertain_text(e, system) for e in self.scene.uncertain],
                "summary": [{k: (json_number(v) if isinstance(v, float) else v) for k, v in r.items()}
                            for r in self.shown_summary(system).to_dict(orient="records")],
                "wall_time_s": round(self.wall_time_s, 3), "simulation_time_s": round(self.sim_time_s, 3)}


def run(scene: Scene, model, n: int, seed: int | None = None, progress: bool = False) -> MonteCarloResult:
    """N draws of the scene's uncertain parameters simulated with `model` (a CollisionModel) as a population
    (model.simulate_population: one scene, the draws as rows). InputError when the scene has no [[uncertain]]
    entries. progress: a tqdm bar on stderr over the blocks of draws."""
    import pandas as pd
    entries = scene.uncertain
    if not entries:
        raise InputError(scene.source, "uncertain", "the scene has no [[uncertain]] parameters to draw "
                         "(crashlab.uncertainty: field, distribution and its parameters)")
    if n < 1:
        raise InputError("command line", "--monte-carlo", f"at least 1 draw, got {n}")
    t0 = time.perf_counter()
    X = uncertainty.sample(entries, n, np.random.default_rng(seed))
    paths = [e.field for e in entries]
    names = scene.vehicle_names
    nominal = _nominal(model, scene)
    parts, sim = [], 0.0
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=n, unit="draw", desc=f"Monte Carlo ({model.name})", dynamic_ncols=True)
    for start in range(0, n, BATCH):
        t1 = time.perf_counter()
        parts.append(_simulate(model, Variants(scene, tuple(paths), X[start:start + BATCH])))
        sim += time.perf_counter() - t1
        if bar is not None:
            bar.update(len(parts[-1]))
    if bar is not None:
        bar.close()
    pop = Population.concat(parts)
    moving = pop.ok[:, None] & ~pop.at_rest
    reasons = pop.reason.copy()
    for k in np.flatnonzero(moving.any(axis=1)):
        reasons[k] = f"{', '.join(n for i, n in enumerate(names) if moving[k, i])} still moving at the end of the run"
    cols = {"draw": np.arange(n)}
    for j, path in enumerate(paths):
        cols[path] = X[:, j]
    for i, name in enumerate(names):
        cols[f"{name}.x"], cols[f"{name}.y"] = pop.rest[:, i, 0], pop.rest[:, i, 1]  # NaN where a run failed
        cols[f"{name}.heading"] = np.degrees(pop.rest[:, i, 2])
        cols[f"{name}.delta_v"] = ms_to_kmh(pop.first_delta_v[:, i])
        cols[f"{name}.ok"] = pop.ok & pop.at_rest[:, i]
    cols["ok"] = reasons == ""
    cols["no_contact"] = pop.ok & (pop.n_impacts == 0)
    cols["reason"] = reasons
    # the draws' model warnings (a population without the column, of an older model: none known)
    cols["warnings"] = getattr(pop, "warnings", np.full(n, "", dtype=object))
    return MonteCarloResult(scene, model.name, seed, pd.DataFrame(cols), nominal,
                            time.perf_counter() - t0, sim)


# warnings.csv's run of the nominal run's warnings (the scene as written, not drawn)
NOMINAL = "the scene as written"


def _nominal(model, scene) -> Outcome:
    """The Outcome of the scene as written; a run that raises (not bad input) as a failed Outcome."""
    try:
        return model.simulate(scene)
    except InputError:
        raise
    except Exception as err:  # noqa: BLE001
        return Outcome.failed(scene.vehicle_names, f"model raised {type(err).__name__}: {err}", model.name)


def _simulate(model, draws: Variants) -> Population:
    """The population of a block of draws (a draw that is no valid scene fails with the reason); a block that
    raises (not bad input) is run draw by draw, and a draw that raises fails with the exception."""
    try:
        return draws.simulate(model)
    except InputError:
        raise
    except Exception:  # noqa: BLE001 - draw by draw, to name the draw that breaks
        return evaluate_variants(model, draws)


# ---------------------------------------------------------------- output
def write(result: MonteCarloResult, out_dir, system: str = "si") -> list[Path]:
    """DIR/montecarlo.csv, DIR/montecarlo.png (rest clouds and delta-V histograms), DIR/summary.csv,
    DIR/warnings.csv (each kind of the model's warnings, the draws that gave it, of how many, run "draws"; then the
    nominal run's, run "the scene as written", 1 of 1; a header only without any); in US units with system "us"
    (montecarlo.csv's converted columns named with their unit, summary.csv with a unit column)."""
    import pandas as pd
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
        paths = [out / "montecarlo.csv", out / "summary.csv", out / "montecarlo.png", out / "warnings.csv"]
        # 10 significant figures: a draw re-runs from its row (its parameters set on the scene give its rest poses)
        frame_in(result.table.drop(columns="warnings"), system, result.table_units()).to_csv(
            paths[0], index=False, float_format="%.10g")
        (result.summary() if system == "si" else result.shown_summary(system)).to_csv(paths[1], index=False,
                                                                                      float_format="%.6g")
        figure(result, paths[2], system)
        pd.DataFrame([{"warning": w, "draws": k, "of": result.n, "run": "draws"} for w, k in result.warning_counts()]
                     + [{"warning": str(w), "draws": 1, "of": 1, "run": NOMINAL} for w in result.nominal.warnings],
                     columns=["warning", "draws", "of", "run"]).to_csv(paths[3], index=False)
    except OSError as err:
        raise InputError(out_dir, "--out", err.strerror or str(err)) from None
    return paths


def _ellipse(ax, xy, colour, share=0.90):
    """The ellipse of the cloud's covariance holding `share` of a Gaussian with it (chi-square, 2 dof)."""
    from matplotlib.patches import Ellipse
    if len(xy) < 3:
        return
    cov = np.cov(xy.T)
    if not np.all(np.isfinite(cov)):
        return
    vals, vecs = np.linalg.eigh(cov)
    r = math.sqrt(-2.0 * math.log(1.0 - share))  # chi-square quantile, 2 dof
    w, h = 2 * r * np.sqrt(np.maximum(vals, 0.0))
    ang = math.degrees(math.atan2(vecs[1, 1], vecs[0, 1]))
    ax.add_patch(Ellipse(xy.mean(axis=0), h, w, angle=ang, fill=False, color=colour, lw=1.5, ls="--"))


def figure(result: MonteCarloResult, path, system: str = "si") -> None:
    """Left: top view with the nominal start (dotted) and rest (solid) outlines, each vehicle's cloud of
    rest positions (CG), its 90 % covariance ellipse (dashed) and its 5-95 % ranges in x and y around the
    median (cross). Right: the delta-V histogram of each vehicle (median and 5-95 % marked)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from crashlab.scene import vehicle_outline
    scene, tab, names = result.scene, result.table, result.names
    ok = tab[tab["ok"]]
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    fig = plt.figure(figsize=(12, max(5.0, 2.6 * len(names))))
    gs = fig.add_gridspec(len(names), 2, width_ratios=(2.2, 1.0))
    ax = fig.add_subplot(gs[:, 0])
    from crashlab.tools.plotting import draw_road
    draw_road(ax, scene.road)  # friction zones shaded and road lines, as in the single run's top view
    nom = result.nominal
    for i, v in enumerate(scene.vehicles):
        c = colours[i % len(colours)]
        poly = vehicle_outline(v)
        ax.plot(*np.vstack([poly, poly[:1]]).T, ":", color=c, label=f"{v.name} start")
        if nom.outcome_ok:
            r = nom.rest_si[i]
            poly = vehicle_outline(v, r[0], r[1], r[2])
            ax.plot(*np.vstack([poly, poly[:1]]).T, "-", color=c, lw=1.2, label=f"{v.name} nominal rest")
        xy = ok[[f"{v.name}.x", f"{v.name}.y"]].to_numpy()
        if len(xy):
            ax.scatter(xy[:, 0], xy[:, 1], s=2, color=c, alpha=min(0.5, 300.0 / len(xy) + 0.05), lw=0,
                       label=f"{v.name} rest CG ({len(xy)} draws)")
            _ellipse(ax, xy, c)
            (x5, x50, x95), (y5, y50, y95) = (np.quantile(xy[:, j], QUANTILES) for j in (0, 1))
            ax.errorbar([x50], [y50], xerr=[[x50 - x5], [x95 - x50]], yerr=[[y50 - y5], [y95 - y50]],
                        color="k", lw=1, capsize=3)
    for b in scene.barriers:
        from crashlab.scene import barrier_outline
        ax.fill(*barrier_outline(b).T, color="0.3")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    length_axes_in(ax, system)
    failed = result.n - len(ok)
    warned = int((tab["warnings"] != "").sum())  # the kinds and their counts: warnings.csv, the summary
    ax.set_title(f"{scene.name} ({result.model}): {result.n} draws, {failed} failed"
                 + (f", {warned} with model warnings (warnings.csv)" if warned else "") + "\n"
                 "rest CG clouds, 90 % ellipses (dashed), median with 5-95 % (cross)", fontsize=9)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=3, markerscale=4)
    ax.grid(alpha=0.3)
    for i, n in enumerate(names):
        h = fig.add_subplot(gs[i, 1])
        vals = value_in(ok[f"{n}.delta_v"].to_numpy(), "km/h", system)
        c = colours[i % len(colours)]
        if len(vals):
            h.hist(vals, bins=40, color=c, alpha=0.7)
            for q, ls in zip(np.quantile(vals, QUANTILES), (":", "-", ":")):
                h.axvline(q, color="k", ls=ls, lw=1)
        h.set_title(f"{n}: delta-V in its first impact", fontsize=9)
        h.set_xlabel(f"delta-V [{unit_in('km/h', system)}]")
        h.set_ylabel("draws")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def print_summary(result: MonteCarloResult, file=None, system: str = "si") -> None:
    """The per-vehicle medians and 5-95 % ranges (in `system`'s units), the failed draws and their reasons."""
    import sys
    file = file or sys.stdout
    tab = result.table
    nfail = int((~tab["ok"]).sum())
    print(f"{result.scene.name} — model {result.model}, Monte Carlo of {result.n} draws (seed {result.seed}), "
          f"{result.wall_time_s:.2f} s ({result.sim_time_s:.2f} s simulating)", file=file)
    print("uncertain parameters:", file=file)
    for e in result.scene.uncertain:
        print(f"  {uncertain_text(e, system)}", file=file)
    print(f"rest pose and delta-V over the {result.n - nfail} draws that did not fail: median [5 %, 95 %]", file=file)
    s = result.shown_summary(system)
    for n in result.names:
        parts = []
        for _, r in s[s.vehicle == n].iterrows():
            unit = r.unit + (" (continuous: turns since the start count)" if r.quantity == "heading" else "")
            parts.append(f"{r.quantity} {r['median']:.2f} [{r.p5:.2f}, {r.p95:.2f}] {unit}")
        print(f"  {n}: " + "; ".join(parts), file=file)
    nc = int(tab["no_contact"].sum())
    if nc:
        print(f"{nc} draws without contact between the vehicles (delta-V 0)", file=file)
    print(f"failed draws: {nfail} of {result.n}" + (":" if nfail else ""), file=file)
    for why, count in result.failure_reasons().items():
        print(f"  {count} x {why}", file=file)
    counts = result.warning_counts()
    print("the model's warnings in the draws" + (":" if counts else ": none"), file=file)
    for w, k in counts:
        print(f"  in {k} of {result.n} draws: {w}", file=file)
    for w in result.nominal.warnings:
        print(f"  the scene as written: {w}", file=file)


def print_warnings(result: MonteCarloResult, file=None) -> None:
    """The model's warnings of the draws on `file` (stderr), a line per kind with the number of draws that gave
    it (warning_counts), and the nominal run's (the scene as written)."""
    import sys
    file = file or sys.stderr
    for w, k in result.warning_counts():
        print(f"warning (Monte Carlo, {result.model}): in {k} of {result.n} draws: {w}", file=file)
    for w in result.nominal.warnings:
        print(f"warning ({result.model}, the scene as written): {w}", file=file)
