"""Command line: crashlab models | vehicles | simulate | compare | reconstruct | infer | study | bench | stress | schema

Bad input exits with status 2 and one line naming the file, the key and the problem; a simulation that
failed (the model's own failure or a physics-guard violation) exits with status 3 and one line.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from ..errors import InputError
from ..registry import UnknownPluginError
from ..units import wrap_deg
from ..version import package_version


class HelpFormatter(argparse.HelpFormatter):
    """Every option's help ends with its default, unless the help already says it or there is none to show
    (a flag, an option that is off without a value)."""

    def _get_help_string(self, action):
        text = action.help or ""
        if (not action.option_strings or "default" in text or action.default in (None, False)
                or action.default is argparse.SUPPRESS):
            return text
        return text + " (default: %(default)s)"


def _num(v):
    """A JSON number: None for NaN or inf (JSON has neither)."""
    try:
        v = float(v)
    except (TypeError, ValueError):
        return None
    return round(v, 6) if math.isfinite(v) else None


# units of the JSON keys of `simulate --json` and `compare --json` (the same shape for both)
JSON_UNITS = {"x": "m", "y": "m", "heading": "deg, wrapped to (-180, 180]",
              "heading_continuous": "deg, continuous: the start heading plus every turn",
              "yaw_turned": "deg, continuous: rest heading minus start heading (two spins add 720)",
              "speed": "km/h", "vx": "km/h, global", "vy": "km/h, global", "yaw_rate": "deg/s", "wall_time_s": "s",
              "d_<source>_m": "m, distance of a model's rest position to the reference's",
              "d_<source>_deg": "deg, wrapped to (-180, 180], model heading minus reference heading"}


def result_json(scene, out) -> dict:
    """One entry of "results": Outcome.to_json_dict() (model, ok, vehicles, impacts, warnings, violations,
    rolled_over, wall_time_s) with each rest pose's heading wrapped to (-180, 180] and, beside it,
    heading_continuous and yaw_turned (JSON_UNITS)."""
    d = out.to_json_dict()
    start = {v.name: math.degrees(v.heading) for v in scene.vehicles}
    for name, veh in d["vehicles"].items():
        rest = veh["rest"]
        h = rest["heading"]
        rest["heading"] = None if h is None else _num(wrap_deg(h))
        rest["heading_continuous"] = h
        rest["yaw_turned"] = None if h is None else _num(h - start[name])
    return d


def results_json(scene_file, scene, outcomes: dict) -> dict:
    """The one JSON shape of `simulate --json` (one result) and `compare --json` (one per model):
    {"scene": {"name", "file"}, "results": [result_json ...], "references": {source: {vehicle: {x, y,
    heading, ...}}}, "comparison": [a row of crashlab.tools.compare.comparison_table per source and vehicle],
    "units": JSON_UNITS | the impact table's units}."""
    from ..outcome import IMPACT_UNITS
    from ..tools.compare import comparison_table
    table = comparison_table(scene, outcomes)
    comparison = [{k: (v if isinstance(v, (str, bool)) or v is None else _num(v)) for k, v in row.items()}
                  for row in table.astype(object).to_dict(orient="records")]
    references = {src: {n: {k: _num(v) for k, v in ref.items()} for n, ref in per.items()}
                  for src, per in scene.references.items()}
    return {"scene": {"name": scene.name, "file": str(scene_file)},
            "results": [result_json(scene, out) for out in outcomes.values()],
            "references": references, "comparison": comparison,
            "units": {**JSON_UNITS, **{f"impacts.{k}": u for k, u in IMPACT_UNITS.items()}}}


def cmd_vehicles(args):
    from .vehicles import format_library_table
    print(format_library_table())
    return 0


def cmd_models(args):
    from ..registry import MODELS, available_models, available_optimizers, load
    if args.options:
        from tabulate import tabulate

        from ..options import describe
        try:
            cls = load(MODELS, args.options)
        except UnknownPluginError as err:
            raise InputError("command line", "--options", str(err)) from None
        rows = describe(getattr(cls, "Options", None))
        if not rows:
            print(f"model {args.options!r} takes no options")
            return 0
        print(f"options of model {args.options!r} (accuracy: the direction that makes a knob finer)")
        print(tabulate([[r["name"], r["type"], r["unit"], r["default"], r["range"], r["accuracy"],
                         r["description"]] for r in rows],
                       headers=["option", "type", "unit", "default", "range", "accuracy", "meaning"],
                       tablefmt="simple", maxcolwidths=[None, None, None, None, None, None, 70]))
        return 0
    print("models:     " + ", ".join(available_models()))
    print("optimizers: " + ", ".join(available_optimizers()))
    return 0


def _get_model(name, where):
    from ..registry import get_model
    try:
        return get_model(name)
    except (UnknownPluginError, TypeError) as err:
        raise InputError(where, "--model", str(err)) from None


def cmd_monte_carlo(args, scene, model):
    """`simulate SCENE --monte-carlo N`: the scene's [[uncertain]] parameters drawn N times
    (crashlab.reconstruction.montecarlo)."""
    from crashlab.reconstruction import montecarlo
    if args.monte_carlo < 1:
        raise InputError("command line", "--monte-carlo", f"at least 1 draw, got {args.monte_carlo}")
    if args.seed is not None and not 0 <= args.seed < 2**32:
        raise InputError("command line", "--seed", f"in [0, 2^32), got {args.seed}")
    if args.plot:
        raise InputError("command line", "--plot", "with --monte-carlo the figure goes to --out DIR")
    if args.csv:
        raise InputError("command line", "--csv", "with --monte-carlo the tables go to --out DIR")
    if args.animate:
        raise InputError("command line", "--animate", "animates a single run, not --monte-carlo")
    if not scene.uncertain:
        raise InputError(args.scene, "uncertain", "--monte-carlo needs [[uncertain]] parameters in the scene "
                         "(field, distribution and its parameters); this scene has none")
    result = montecarlo.run(scene, model, args.monte_carlo, 1 if args.seed is None else args.seed)
    written = montecarlo.write(result, args.out) if args.out else []
    if args.json:
        print(json.dumps(result.to_json_dict(), indent=2))
    else:
        montecarlo.print_summary(result)
        if written:
            print("wrote " + ", ".join(str(p) for p in written))
        else:
            print("(--out DIR writes the table of draws and the figure)")
    return 0


def _write_csv(out, folder: Path) -> None:
    """DIR/trajectories.csv (vehicle, t [s], x, y [m], heading [deg, continuous], vx, vy [km/h], yaw_rate
    [deg/s], and z [m], roll, pitch [deg] where the model records them) and DIR/impacts.csv (Outcome.impacts:
    units in its docstring); written for a failed run too (it shows where it went wrong)."""
    import pandas as pd
    try:
        folder.mkdir(parents=True, exist_ok=True)
        frames = [out.trajectory(n).assign(vehicle=n) for n in out.names if n in (out.trajectories or {})]
        traj = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=["vehicle", "t"])
        traj[["vehicle"] + [c for c in traj.columns if c != "vehicle"]].to_csv(folder / "trajectories.csv",
                                                                             index=False)
        out.impacts.to_csv(folder / "impacts.csv", index=False)
    except OSError as err:
        raise InputError(str(folder), "--csv", f"cannot write there ({err.strerror or err})") from None


def _rest_table(scene, out):
    """The end poses for printing: x, y [m], heading wrapped to (-180, 180] [deg], yaw turned since the
    start (continuous) [deg], speed [km/h], at_rest."""
    rest = out.rest
    start = [math.degrees(v.heading) for v in scene.vehicles]
    table = rest[["x", "y"]].copy()
    table["heading [deg, -180..180]"] = wrap_deg(rest["heading"].to_numpy())
    table["yaw turned [deg]"] = rest["heading"].to_numpy() - start
    table["speed [km/h]"] = rest["speed"]
    table["at_rest"] = rest["at_rest"]
    return table.rename(columns={"x": "x [m]", "y": "y [m]"})


def cmd_simulate(args):
    from ..scene_file import load_scene
    animate = None
    if args.animate:
        from ..tools.animation import check_animation_path
        animate = check_animation_path(args.animate, "--animate")  # before the run: refused at once
        if not args.fps > 0 or not args.slow_motion > 0:
            raise InputError("command line", "--fps" if not args.fps > 0 else "--slow-motion",
                             f"must be positive, got {args.fps if not args.fps > 0 else args.slow_motion}")
    scene = load_scene(args.scene)
    model = _get_model(args.model, args.scene)
    if args.monte_carlo is not None:
        return cmd_monte_carlo(args, scene, model)
    if args.seed is not None or args.out is not None:
        raise InputError("command line", "--seed" if args.seed is not None else "--out",
                         "only with --monte-carlo N")
    out = model.simulate(scene)
    if args.csv:
        _write_csv(out, Path(args.csv))
    if args.plot:
        from ..tools.plotting import top_view
        try:
            top_view(scene, out, args.plot)
        except (OSError, ValueError) as err:
            raise InputError(args.plot, "--plot", str(err).splitlines()[0]) from None
    if animate and not out.trajectories and out.outcome_ok:
        raise InputError(str(animate), "--animate", f"model {out.model or args.model} records no trajectories to "
                         "animate")
    if animate and out.trajectories:
        from ..tools.animation import write_animation
        try:
            write_animation(scene, out, animate, fps=args.fps, speed=1.0 / args.slow_motion)
        except (OSError, ValueError) as err:
            raise InputError(str(animate), "--animate", str(err).splitlines()[0]) from None
    if args.json:
        print(json.dumps(results_json(args.scene, scene, {out.model or args.model: out}), indent=2))
    if not out.outcome_ok:
        print(f"crashlab: simulation failed: {args.scene}: model {out.model}: {'; '.join(out.warnings)}",
              file=sys.stderr)
        return 3
    if args.json:
        return 0
    import pandas as pd
    with pd.option_context("display.float_format", "{:.3f}".format, "display.width", 160):
        print(f"{scene.name} — model {out.model}, {out.wall_time_s * 1e3:.1f} ms")
        print("end pose:")
        print(_rest_table(scene, out).to_string())
        for i, n in enumerate(out.names):
            if not out.at_rest_mask[i]:
                print(f"{n}: {out.pose_label(i)} at t = {out.diagnostics.get('t_end', scene.duration):.2f} s, "
                      "not a rest pose")
        print("final velocity:")
        print(out.final.rename(columns={"vx": "vx [km/h]", "vy": "vy [km/h]", "yaw_rate": "yaw_rate [deg/s]"})
              .to_string())
        if len(out.impacts):
            print("impacts:")
            from ..outcome import IMPACT_UNITS
            table = out.impacts.drop(columns=["plane_angle"])
            print(table.rename(columns={c: f"{c} [{IMPACT_UNITS[c]}]" for c in table if c in IMPACT_UNITS})
                  .to_string(index=False))
    for w in out.warnings:
        print("warning:", w)
    return 0


def cmd_compare(args):
    import pandas as pd

    from ..scene_file import load_scene
    from ..tools.compare import comparison_table, with_unit_headers
    scene = load_scene(args.scene)
    models = [m.strip() for m in args.models.split(",") if m.strip()]
    if not models:
        raise InputError("command line", "--models", "give at least one model name")
    resolved = {m: _get_model(m, args.scene) for m in models}
    outcomes = {m: model.simulate(scene) for m, model in resolved.items()}
    failed = [m for m, out in outcomes.items() if not out.outcome_ok]
    if args.plot:
        from ..tools.plotting import compare_view
        try:
            compare_view(scene, outcomes, args.plot)
        except (OSError, ValueError) as err:
            raise InputError(args.plot, "--plot", str(err).splitlines()[0]) from None
    if args.json:
        print(json.dumps(results_json(args.scene, scene, outcomes), indent=2))
        for m in failed:
            print(f"crashlab: simulation failed: {args.scene}: model {m}: {'; '.join(outcomes[m].warnings)}",
                  file=sys.stderr)
        return 3 if failed else 0
    df = comparison_table(scene, outcomes)
    with pd.option_context("display.float_format", "{:.2f}".format, "display.width", 250,
                           "display.max_columns", 30):
        print(f"{scene.name}: end pose, final velocity; d_<source>: difference to a published result "
              "(heading wrapped; yaw turned: continuous, since the start)")
        print(with_unit_headers(df).to_string(index=False))
    for m, out in outcomes.items():
        for w in out.warnings:
            print(f"warning ({m}):", w)
    for m in failed:
        print(f"crashlab: simulation failed: {args.scene}: model {m}: {'; '.join(outcomes[m].warnings)}",
              file=sys.stderr)
    return 3 if failed else 0


def cmd_bench(args):
    from ..tools.bench import run_bench
    _get_model(args.model, args.scene or "crashlab bench")
    if args.batch < 1 or args.repeat < 1:
        raise InputError("crashlab bench", "--batch/--repeat", "must be at least 1")
    run_bench(args.model, args.scene, args.batch, args.repeat)
    return 0


def cmd_damage(args):
    """`crashlab damage`: CRASH3 crush energy, EES and delta-V from a crush profile (crashlab.damage)."""
    from .damage import command
    print(command(args.target, args.side, args.profile, args.width, args.offset, args.pdof, args.vehicle,
                  args.other, args.restitution, args.json))
    return 0


def cmd_examples(args):
    """`crashlab examples`: the bundled examples and vehicles; `crashlab examples copy DIR` writes them out."""
    from ..tools import examples
    if args.action is None:
        rows = [(rel, examples.describe(p)) for rel, p in examples.files()]
        width = max(len(r) for r, _ in rows)
        print("\n".join(f"{r:<{width}}  {d}" for r, d in rows))
        print(f"\n{len(rows)} files; `crashlab examples copy DIR` writes them to DIR")
        return 0
    if args.action != "copy" or not args.dir:
        raise InputError("command line", "examples", "give nothing (list) or `copy DIR`")
    written = examples.copy(args.dir)
    side = Path(args.dir) / "pc_crash" / "side.toml"
    print(f"wrote {len(written)} files to {args.dir} (try: crashlab compare {side} --models impulse)")
    return 0


def cmd_stress(args):
    from ..tools import stress
    model = _get_model(args.model, "crashlab stress")
    if args.runs < 0:
        raise InputError("crashlab stress", "--runs", "must be at least 0")
    df = stress.sweep(model, stress.random_scenes(args.runs, args.seed) + stress.extreme_scenes())
    if args.csv:
        try:
            df.to_csv(args.csv, index=False)
        except OSError as err:
            raise InputError(args.csv, "--csv", str(err)) from None
    s = stress.summary(df)
    print(f"model {args.model}: {s['runs']} runs (seed {args.seed}, + {len(stress.extreme_scenes())} extremes), "
          f"{s['caught']} caught by the guard or failed: {s['by_kind'] or 'none'}; "
          f"{s['moving_at_end']} with a vehicle moving at the end, {s['rolled_over']} rolled over")
    for _, r in df[~df.ok].iterrows():
        print(f"  {r.scene} ({r.speeds_kmh} km/h, {r.masses_kg} kg, {r.wheels}): {r.reason}")
    return 0


def cmd_reconstruct(args):
    from crashlab.reconstruction import run_cli
    return run_cli(args)


def cmd_infer(args):
    from crashlab.reconstruction.infer import cmd_infer as run
    return run(args)


def cmd_study(args):
    from crashlab.comparison.command import run_cli
    return run_cli(args)


def cmd_schema(args):
    from .schema_docs import TITLES, json_schema, reference_markdown, schema_roots
    roots = schema_roots()
    if args.markdown:
        if args.kind:
            raise InputError("command line", "--markdown", "prints the reference of every file kind: give no kind")
        print(reference_markdown(roots), end="")
        return 0
    if not args.kind:
        raise InputError("command line", "schema", "give scene, study or vehicle (or --markdown)")
    model, extras = roots[args.kind]
    print(json.dumps(json_schema(model, extras, title=f"crashlab {TITLES[args.kind].lower()}"), indent=2))
    return 0


def build_parser():
    p = argparse.ArgumentParser(prog="crashlab", description=__doc__.splitlines()[0], formatter_class=HelpFormatter)
    p.add_argument("--version", action="version", version=f"crashlab {package_version()}",
                   help="print the installed version and exit")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def command(name, help):
        return sub.add_parser(name, help=help, description=help, formatter_class=HelpFormatter)

    mo = command("models", "list the registered collision models and optimizers")
    mo.add_argument("--options", metavar="NAME", help="list the options of model NAME with unit, range, default "
                    "and accuracy direction (without it: the names of every model and optimizer)")
    mo.set_defaults(fn=cmd_models)
    ve = command("vehicles", "list the vehicle library: class, mass, size, wheelbase, yaw inertia and whether it "
                 "is measured, published or an estimate")
    ve.set_defaults(fn=cmd_vehicles)
    s = command("simulate", "simulate a scene file and print the end poses, final velocities and impacts")
    s.add_argument("scene", help="scene TOML file (docs/reference.md)")
    s.add_argument("--model", default="impulse", help="collision model (crashlab models lists them)")
    s.add_argument("--json", action="store_true", help="print JSON instead of tables: the shape of compare --json "
                   "with one result ({scene, results, references, comparison, units})")
    s.add_argument("--plot", metavar="FILE", help="write the top view (PNG, PDF, SVG)")
    s.add_argument("--csv", metavar="DIR", help="write DIR/trajectories.csv (vehicle, t [s], x, y [m], heading "
                   "[deg, continuous], vx, vy [km/h], yaw_rate [deg/s]) and DIR/impacts.csv")
    s.add_argument("--animate", metavar="FILE", help="write an animation, FILE.gif (Pillow) or FILE.mp4 (needs "
                   "ffmpeg on PATH): outlines with headings, growing CG paths, impacts flashed, time stamp")
    s.add_argument("--fps", type=float, default=25.0, help="--animate: frames per second of playback")
    s.add_argument("--slow-motion", type=float, default=1.0, metavar="FACTOR",
                   help="--animate: play FACTOR times slower than real time (at most 300 frames: a long run "
                   "plays faster)")
    s.add_argument("--monte-carlo", type=int, default=None, metavar="N",
                   help="draw the scene's [[uncertain]] parameters N times and simulate each draw (default: "
                   "one run of the nominal scene)")
    s.add_argument("--seed", type=int, default=None, help="--monte-carlo: seed of the draws (default: 1)")
    s.add_argument("--out", default=None, metavar="DIR", help="--monte-carlo: write montecarlo.csv, summary.csv "
                   "and montecarlo.png here (default: print the summary only)")
    s.set_defaults(fn=cmd_simulate)
    c = command("compare", "compare models with each other and with the scene's published results")
    c.add_argument("scene", help="scene TOML file, optionally with [reference.SOURCE.VEHICLE] tables")
    c.add_argument("--models", default="impulse", metavar="A,B", help="comma-separated model names")
    c.add_argument("--json", action="store_true", help="print JSON instead of the table: {scene, results (one per "
                   "model), references, comparison, units}")
    c.add_argument("--plot", metavar="FILE", help="write one top view with every model's paths and end poses and "
                   "the published rest poses (PNG, PDF, SVG)")
    c.set_defaults(fn=cmd_compare)
    b = command("bench", "simulations per second, single and batched")
    b.add_argument("--model", default="impulse", help="collision model")
    b.add_argument("--scene", default=None, help="scene file (default: the bundled side collision)")
    b.add_argument("--batch", type=int, default=1000, help="scenes per batched call")
    b.add_argument("--repeat", type=int, default=3, help="timed repetitions (the best one counts)")
    b.set_defaults(fn=cmd_bench)
    d = command("damage", "CRASH3 crush energy, EES and delta-V from a measured crush profile (docs/physics.md)")
    d.add_argument("target", metavar="SCENE|VEHICLE", help="a scene file (with --vehicle) or a vehicle name/file")
    d.add_argument("--side", required=True, choices=["front", "rear", "side"], help="the damaged side")
    d.add_argument("--profile", required=True, metavar="C1,...,Cn", help="crush depths [m], 2, 4 or 6 points")
    d.add_argument("--width", required=True, type=float, help="damaged width [m]")
    d.add_argument("--offset", type=float, default=0.0, help="m, the damage centre left of the centreline "
                   "(front/rear) or ahead of the CG (side)")
    d.add_argument("--pdof", type=float, default=None, help="deg in the vehicle's axes: 0 from ahead, +90 from "
                   "the left (default: none, no correction)")
    d.add_argument("--vehicle", default=None, help="the scene's vehicle (by name)")
    d.add_argument("--with", dest="other", default=None, metavar="VEHICLE:SIDE:C1,..,Cn:WIDTH[:OFFSET[:PDOF]]",
                   help="a second vehicle's damage: both delta-Vs")
    d.add_argument("--restitution", type=float, default=0.0, help="with --with: the impact's restitution")
    d.add_argument("--json", action="store_true", help="print JSON")
    d.set_defaults(fn=cmd_damage)
    ex = command("examples", "the bundled example scenes, studies and vehicles; `copy DIR` writes them out")
    ex.add_argument("action", nargs="?", choices=["copy"], help="copy: write every example to DIR")
    ex.add_argument("dir", nargs="?", metavar="DIR", help="a new or empty folder")
    ex.set_defaults(fn=cmd_examples)
    st = command("stress", "seeded random crashes judged by the physics guard")
    st.add_argument("--model", default="impulse", help="collision model")
    st.add_argument("--runs", type=int, default=100, help="random scenes (the fixed extreme scenes run besides)")
    st.add_argument("--seed", type=int, default=1, help="seed of the random scenes")
    st.add_argument("--csv", default=None, metavar="FILE", help="write one row per run (default: none written)")
    st.set_defaults(fn=cmd_stress)
    inf = command("infer", "sample the posterior of a study's free variables and uncertain parameters given its "
                  "evidence (with sigmas)")
    inf.add_argument("study", help="study TOML file with the evidence's sigmas")
    inf.add_argument("--out", required=True, metavar="DIR",
                     help="output directory (posterior.csv, summary.md, figures, checkpoint); required")
    inf.add_argument("--samples", type=int, default=None, help="kept posterior samples (default: [infer] samples)")
    inf.add_argument("--seed", type=int, default=None, help="sampler seed (default: [infer] seed)")
    inf.add_argument("--resume", action="store_true", help="continue from DIR's checkpoint")
    inf.add_argument("--workers", type=int, default=None, help="worker processes (default: the study's [execution])")
    inf.add_argument("--no-progress", action="store_true", help="no progress line")
    inf.set_defaults(fn=cmd_infer)
    r = command("reconstruct", "search the pre-impact conditions that explain the evidence")
    r.add_argument("study", help="study TOML file (docs/reference.md)")
    r.add_argument("--optimizer", default=None, metavar="NAME",
                   help="optimizer (default: the study's [optimizer] name)")
    r.add_argument("--workers", type=int, default=None, help="worker processes (default: the study's [execution])")
    r.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="address of a Dask scheduler to evaluate on (default: the study's [execution] scheduler, "
                   "else local workers)")
    r.add_argument("--resume", action="store_true", help="continue from --out DIR's checkpoint")
    r.add_argument("--out", default=None, metavar="DIR",
                   help="write the Pareto set, report and figures here (default: print only)")
    r.add_argument("--json", action="store_true", help="print the result as JSON")
    r.add_argument("--no-progress", action="store_true", help="no progress line")
    r.set_defaults(fn=cmd_reconstruct)
    sd = command("study", "comparison studies of the models: run time against error, stability, scaling, "
                 "validation, the PC-Crash cases with every impulse law")
    sd.add_argument("name", help="workprecision | stability | scaling | validation | pc_crash | all")
    sd.add_argument("--models", default=None, help="comma-separated model names (default: every registered model)")
    sd.add_argument("--quick", action="store_true", help="a small configuration (minutes, not hours)")
    sd.add_argument("--out", required=True, metavar="DIR", help="folder for the CSV files and figures; required")
    sd.set_defaults(fn=cmd_study)
    sc = command("schema", "print the JSON Schema of a scene, study or vehicle file (for editors' completion and "
                 "checking), or with --markdown the reference of every key (docs/reference.md)")
    sc.add_argument("kind", nargs="?", choices=["scene", "study", "vehicle"], help="the file kind")
    sc.add_argument("--markdown", action="store_true", help="print docs/reference.md: every key of the three file "
                    "kinds with type, unit, range, default and meaning")
    sc.set_defaults(fn=cmd_schema)
    return p


def main(argv=None):
    args = build_parser().parse_args(argv)
    try:
        return args.fn(args)
    except InputError as err:
        print(f"crashlab: error: {err}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        return 0
