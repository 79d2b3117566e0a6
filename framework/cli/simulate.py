"""`crashlab simulate` and `crashlab compare`: a scene run by one or more models, its tables, JSON, CSV, plots,
animation and Monte Carlo."""
from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

from ..errors import InputError
from ..execution.constants import TIMEOUT_MIN_S
from ..registry import UnknownPluginError, listed_models
from ..units import json_in, json_number, table_in, wrap_deg

# units of the JSON keys of `simulate --json` and `compare --json` (the same shape for both)
# impact-table columns printed with --wide only (the default table fits 100 columns; a reversed slip is also a
# warning of its own)
IMPACT_WIDE_ONLY = ("dvx", "dvy", "pdof_clock", "side", "slip_reversed", "point_x", "point_y", "crush", "peak_force",
                    "duration", "restitution")
JSON_UNITS = {"x": "m", "y": "m", "heading": "deg, wrapped to (-180, 180]",
              "heading_continuous": "deg, continuous: the start heading plus every turn",
              "yaw_turned": "deg, continuous: rest heading minus start heading (two spins add 720)",
              "speed": "km/h", "vx": "km/h, global", "vy": "km/h, global", "yaw_rate": "deg/s", "wall_time_s": "s",
              "d_<source>_m": "m, distance of a model's rest position to the reference's",
              "d_<source>_deg": "deg, wrapped to (-180, 180], model heading minus reference heading",
              "distance_m": "m, spread: the largest distance between two models' rest positions",
              "heading_deg": "deg, spread: the largest wrapped heading difference between two models"}


def result_json(scene, out) -> dict:
    """One entry of "results": Outcome.to_json_dict() (model, ok, vehicles, impacts, warnings, violations,
    rolled_over, wall_time_s) with each rest pose's heading wrapped to (-180, 180] and, beside it,
    heading_continuous and yaw_turned (JSON_UNITS)."""
    d = out.to_json_dict()
    start = {v.name: math.degrees(v.heading) for v in scene.vehicles}
    for name, veh in d["vehicles"].items():
        rest = veh["rest"]
        h = rest["heading"]
        rest["heading"] = None if h is None else json_number(wrap_deg(h))
        rest["heading_continuous"] = h
        rest["yaw_turned"] = None if h is None else json_number(h - start[name])
    return d


def results_json(scene_file, scene, outcomes: dict) -> dict:
    """The one JSON shape of `simulate --json` (one result) and `compare --json` (one per model):
    {"scene": {"name", "file"}, "results": [result_json ...], "references": {source: {vehicle: {x, y,
    heading, ...}}}, "comparison": [a row of crashlab.tools.compare.comparison_table per source and vehicle],
    "spread": [crashlab.tools.compare.model_spread's row per vehicle; empty with fewer than two models],
    "units": JSON_UNITS | the impact table's units}."""
    from ..outcome import IMPACT_UNITS
    from ..tools.compare import comparison_table, model_spread
    table = comparison_table(scene, outcomes)
    comparison = [{k: (v if isinstance(v, (str, bool)) or v is None else json_number(v)) for k, v in row.items()}
                  for row in table.astype(object).to_dict(orient="records")]
    spread = [{k: (v if isinstance(v, (str, int)) else json_number(v)) for k, v in row.items()}
              for row in model_spread(table, outcomes).to_dict(orient="records")]
    # (a reference's heading wrapped as the units map says, as its printed tables show it: 232.55 -> -127.45)
    references = {src: {n: {k: json_number(wrap_deg(v) if k == "heading" else v) for k, v in ref.items()}
                        for n, ref in per.items()} for src, per in scene.references.items()}
    return {"scene": {"name": scene.name, "file": str(scene_file)},
            "results": [result_json(scene, out) for out in outcomes.values()],
            "references": references, "comparison": comparison, "spread": spread,
            "units": {**JSON_UNITS, **{f"impacts.{k}": u for k, u in IMPACT_UNITS.items()}}}


def _get_model(name, where, option: str = "--model"):
    from ..registry import get_model
    try:
        return get_model(name)
    except (UnknownPluginError, TypeError) as err:
        raise InputError(where, option, str(err)) from None


def check_seed(seed: int) -> None:
    """A --seed of the command line within numpy's range (crashlab.reconstruction's SEED_MAX); InputError else."""
    from ..reconstruction.schema import SEED_MAX
    if not 0 <= seed <= SEED_MAX:
        raise InputError("command line", "--seed", f"in [0, {SEED_MAX}], got {seed}")


def refuse_other_kind(path, expected: str, takes: str = "simulate and compare take") -> None:
    """InputError when the file is of the other kind than the command takes: a study (it names its scene and
    has [[free]] or [evidence]) given where a scene is expected, or a scene (it has [[vehicles]] and names
    no scene) given where a study is. `takes`: the commands that take a scene, for the message."""
    from ..input_files import KIND_SIGN, file_kind, read_toml
    data = read_toml(Path(path), "scene" if expected == "scene" else "study")
    kind = file_kind(data)
    if expected == "scene" and kind == "study":
        raise InputError(path, "(top level)", "this is a study file (it names a scene and what to search): run it "
                         f"with crashlab reconstruct or crashlab infer; {takes} a scene file")
    if kind == "vehicle":
        raise InputError(path, "(top level)", f"this is a vehicle file ({KIND_SIGN['vehicle']}): a scene names it "
                         f"in [[vehicles]] (vehicle = \"{Path(path).name}\"); "
                         + (f"{takes} a scene file" if expected == "scene" else "reconstruct and infer take a "
                            "study file"))
    if expected == "study" and kind == "scene":
        raise InputError(path, "(top level)", "this is a scene file (it has [[vehicles]]): run it with crashlab "
                         "simulate or compare; reconstruct and infer take a study file that names a scene "
                         "(docs/tutorial.md)")


def announce_compile(model):
    """Announce on stderr a model's cold compile (the first use of its numba kernels after installing or
    updating crashlab) before it starts; returns what announces its time after it, or None when nothing
    compiles cold."""
    if model.compiles is None:
        return None
    from .. import numba_cache
    if numba_cache.is_cached(model.compiles):
        return None
    print(f"compiling the {model.name} model once (first use after an install or update: about 30 s; "
          "later runs load it)", file=sys.stderr, flush=True)
    t0 = time.perf_counter()

    def compiled():
        print(f"compiled the {model.name} model in {time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
    return compiled


def loaded(model, scene) -> None:
    """Run the model once on the scene, untimed, so that the run that follows times the simulation alone: a
    model with numba kernels (CollisionModel.compiles) loads or compiles them on its first call (a cold
    compile announced, announce_compile)."""
    if model.compiles is None:
        return
    compiled = announce_compile(model)
    try:
        model.simulate(scene)
    except Exception:  # noqa: BLE001 - the timed run that follows meets it and reports it
        pass
    if compiled:
        compiled()


def cmd_monte_carlo(args, scene, model):
    """`simulate SCENE --monte-carlo N`: the scene's [[uncertain]] parameters drawn N times
    (crashlab.reconstruction.montecarlo)."""
    from crashlab.reconstruction import montecarlo
    if args.monte_carlo < 1:
        raise InputError("command line", "--monte-carlo", f"at least 1 draw, got {args.monte_carlo}")
    if args.seed is not None:
        check_seed(args.seed)
    if args.plot:
        raise InputError("command line", "--plot", "with --monte-carlo the figure goes to --out DIR")
    if args.csv:
        raise InputError("command line", "--csv", "with --monte-carlo the tables go to --out DIR")
    if args.animate:
        raise InputError("command line", "--animate", "animates a single run, not --monte-carlo")
    if not scene.uncertain:
        raise InputError(args.scene, "uncertain", "--monte-carlo needs [[uncertain]] parameters in the scene "
                         "(field, distribution and its parameters); this scene has none")
    from ..outdir import lock_out_dir
    with lock_out_dir(args.out, "simulate --monte-carlo"):  # one run writes DIR at a time
        result = montecarlo.run(scene, model, args.monte_carlo, 1 if args.seed is None else args.seed,
                                progress=sys.stderr.isatty())
        written = montecarlo.write(result, args.out, args.units) if args.out else []
    if not result.table["ok"].any():  # no draw to summarise (medians of none): the run failed
        reasons = result.failure_reasons()
        why = f", for {len(reasons)} reasons" if len(reasons) > 1 else ""
        failed = (f"crashlab: simulation failed: {args.scene}: model {result.model}: all {result.n} draws failed{why} "
                  f"(the first: {result.table['reason'].iloc[0]})")
        if args.json:  # the JSON says why each failed (failure_reasons), as a failed single run's does
            print(json.dumps(result.to_json_dict(args.units), indent=2))
        elif written:
            print("wrote " + ", ".join(str(p) for p in written), file=sys.stderr)
        print(failed, file=sys.stderr)
        return 3
    if args.json:  # stderr: each kind of the model's warnings once, with its count of draws (the summary has them)
        montecarlo.print_warnings(result)
        print(json.dumps(result.to_json_dict(args.units), indent=2))
    else:
        montecarlo.print_summary(result, system=args.units)
        if written:  # (on stderr, as a single run's --csv and --plot say theirs)
            print("wrote " + ", ".join(str(p) for p in written), file=sys.stderr)
        else:
            print("(--out DIR writes the table of draws and the figure)")
    return 0


def _cell(v, digits: int = 2) -> str:
    """A table cell: true/false for a boolean, a count as an integer, "-" for a missing number, `digits` decimals
    without a minus zero and with -180 read as 180 (a heading wrapped to (-180, 180] that rounds to the
    boundary)."""
    if v is None or isinstance(v, str):
        return "-" if v is None else v
    if isinstance(v, (bool,)) or type(v).__name__ == "bool_":
        return str(bool(v)).lower()
    if isinstance(v, int) or type(v).__name__.startswith("int"):  # a count
        return str(int(v))
    try:
        x = float(v)
    except (TypeError, ValueError):
        return str(v)
    if not math.isfinite(x):
        return "-"
    text = f"{x:.{digits}f}"
    zero, half_turn = f"{0:.{digits}f}", f"{180:.{digits}f}"
    return {"-" + zero: zero, "-" + half_turn: half_turn}.get(text, text)


def _table_text(df, digits: int = 2) -> str:
    """A printed table: cells by _cell, right-aligned under their headers, two spaces apart (tabulate pads
    every column by two more beyond its widest cell: the pose table took 107 columns)."""
    cells = [[_cell(v, digits) for v in row] for row in df.astype(object).itertuples(index=False)]
    heads = [str(c) for c in df.columns]
    widths = [max([len(h)] + [len(r[k]) for r in cells]) for k, h in enumerate(heads)]
    return "\n".join("  ".join(c.rjust(w) for c, w in zip(row, widths)) for row in [heads] + cells)


def _write_csv(out, folder: Path, units: str = "si") -> None:
    """DIR/trajectories.csv (vehicle, t [s], x, y [m], heading [deg, continuous], vx, vy [km/h], yaw_rate
    [deg/s], and z [m], roll, pitch [deg] where the model records them) and DIR/impacts.csv (Outcome.impacts:
    units in its docstring); written for a failed run too (it shows where it went wrong). units "us": the
    columns with a US unit converted and named with it ("x [ft]", "vx [mph]")."""
    import pandas as pd

    from ..outcome import IMPACT_UNITS, TRAJECTORY_UNITS

    def shown(df, column_units):
        if units == "si":
            return df
        return table_in(df.rename(columns={c: f"{c} [{column_units[c]}]" for c in df if c in column_units}), units)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        frames = [out.trajectory(n).assign(vehicle=n) for n in out.names if n in (out.trajectories or {})]
        traj = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=["vehicle", "t"])
        traj = traj[["vehicle"] + [c for c in traj.columns if c != "vehicle"]]
        shown(traj, TRAJECTORY_UNITS).to_csv(folder / "trajectories.csv", index=False)
        shown(out.impacts, IMPACT_UNITS).to_csv(folder / "impacts.csv", index=False)
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
    from ..tools.plotting import pose_text  # (the end-pose note in the tables' units)
    animate = None
    fps = 25.0 if args.fps is None else args.fps
    slow_motion = 1.0 if args.slow_motion is None else args.slow_motion
    if args.animate:
        from ..tools.animation import check_animation_path
        animate = check_animation_path(args.animate, "--animate")  # before the run: refused at once
        for option, value in (("--fps", fps), ("--slow-motion", slow_motion)):
            if not (math.isfinite(value) and value > 0):
                raise InputError("command line", option, f"must be positive and finite, got {value}")
    elif args.fps is not None or args.slow_motion is not None:
        raise InputError("command line", "--fps" if args.fps is not None else "--slow-motion",
                         "only with --animate FILE")
    refuse_other_kind(args.scene, "scene")
    scene = load_scene(args.scene)
    model = _get_model(args.model, args.scene)
    timeout = getattr(args, "timeout", None)
    if timeout is not None and not (math.isfinite(timeout) and timeout >= TIMEOUT_MIN_S):
        raise InputError("command line", "--timeout", f"seconds, at least {TIMEOUT_MIN_S:g}, got {timeout}")
    if args.monte_carlo is not None:
        if timeout is not None:
            raise InputError("command line", "--timeout", "limits a single run, not --monte-carlo")
        return cmd_monte_carlo(args, scene, model)
    if args.seed is not None or args.out is not None:
        raise InputError("command line", "--seed" if args.seed is not None else "--out",
                         "only with --monte-carlo N")
    if args.plot:
        from ..tools.plotting import check_plot_path
        check_plot_path(args.plot, "--plot")  # before the run: refused at once
    if timeout is None:
        loaded(model, scene)
        out = model.simulate(scene)
    else:
        from ..execution import TimedOut, simulate_with_timeout
        try:  # in a worker process that is killed when it overruns; it warms the model up first
            out = simulate_with_timeout(args.model, scene, timeout, on_ready=announce_compile(model))
        except TimedOut:
            print(f"crashlab: simulation failed: {args.scene}: model {args.model}: the run took longer than "
                  f"--timeout {timeout:g} s and was stopped", file=sys.stderr)
            return 3
        except RuntimeError as err:
            print(f"crashlab: simulation failed: {args.scene}: model {args.model}: {err}", file=sys.stderr)
            return 3
    written = []
    if args.csv:
        _write_csv(out, Path(args.csv), args.units)
        written += [Path(args.csv) / "trajectories.csv", Path(args.csv) / "impacts.csv"]
    if args.plot:
        from ..tools.plotting import top_view
        try:
            top_view(scene, out, args.plot, system=args.units)
        except (OSError, ValueError) as err:
            raise InputError(args.plot, "--plot", str(err).splitlines()[0]) from None
        written.append(args.plot)
    if animate and not out.trajectories and out.outcome_ok:
        raise InputError(str(animate), "--animate", f"model {out.model or args.model} records no trajectories to "
                         "animate")
    if animate and out.trajectories:
        from ..tools.animation import write_animation
        try:
            write_animation(scene, out, animate, fps=fps, speed=1.0 / slow_motion,
                            system=args.units)
        except (OSError, ValueError) as err:
            raise InputError(str(animate), "--animate", str(err).splitlines()[0]) from None
        written.append(animate)
    if written:  # (stderr: --json keeps stdout to the JSON)
        print("wrote " + ", ".join(str(w) for w in written), file=sys.stderr)
    if args.json:
        print(json.dumps(json_in(results_json(args.scene, scene, {out.model or args.model: out}), args.units),
                         indent=2))
    if not out.outcome_ok:
        print(f"crashlab: simulation failed: {args.scene}: model {out.model}: {'; '.join(out.warnings)}",
              file=sys.stderr)
        return 3
    if args.json:
        return 0
    print(f"{scene.name} — model {out.model}, {out.wall_time_s * 1e3:.1f} ms")
    print("end pose:")
    print(_table_text(table_in(_rest_table(scene, out).reset_index(), args.units), digits=3))
    for i, n in enumerate(out.names):
        if not out.at_rest_mask[i]:
            print(f"{n}: {pose_text(out, i, args.units)} at t = {out.diagnostics.get('t_end', scene.duration):.2f} s, "
                  "not a rest pose")
    print("final velocity:")
    final = out.final.rename(columns={"vx": "vx [km/h]", "vy": "vy [km/h]", "yaw_rate": "yaw_rate [deg/s]"})
    print(_table_text(table_in(final.reset_index(), args.units), digits=3))
    if len(out.impacts):
        print("impacts:")
        from ..outcome import IMPACT_UNITS
        hidden = ["plane_angle"] + ([] if args.wide else list(IMPACT_WIDE_ONLY))
        table = out.impacts.drop(columns=hidden, errors="ignore")  # (CONTACT_COLUMNS where the model gives them)
        table = table.rename(columns={c: f"{c} [{IMPACT_UNITS[c]}]" for c in table if c in IMPACT_UNITS})
        print(_table_text(table_in(table, args.units), digits=3))
    for w in out.warnings:
        print("warning:", w)
    return 0


def cmd_compare(args):
    import numpy as np
    import pandas as pd

    from ..scene_file import load_scene
    from ..tools.compare import comparison_table, model_spread, with_unit_headers
    refuse_other_kind(args.scene, "scene")
    scene = load_scene(args.scene)
    try:
        models = listed_models(args.models)
    except ValueError as err:
        raise InputError("command line", "--models", str(err)) from None
    resolved = {m: _get_model(m, args.scene, "--models") for m in models}
    if args.plot:
        from ..tools.plotting import check_plot_path
        check_plot_path(args.plot, "--plot")  # before the runs: refused at once
    for model in resolved.values():
        loaded(model, scene)
    outcomes = {m: model.simulate(scene) for m, model in resolved.items()}
    failed = [m for m, out in outcomes.items() if not out.outcome_ok]
    if args.plot:
        from ..tools.plotting import compare_view
        try:
            compare_view(scene, outcomes, args.plot, system=args.units)
        except (OSError, ValueError) as err:
            raise InputError(args.plot, "--plot", str(err).splitlines()[0]) from None
        print(f"wrote {args.plot}", file=sys.stderr)
    if args.json:
        print(json.dumps(json_in(results_json(args.scene, scene, outcomes), args.units), indent=2))
        for m in failed:
            print(f"crashlab: simulation failed: {args.scene}: model {m}: {'; '.join(outcomes[m].warnings)}",
                  file=sys.stderr)
        return 3 if failed else 0
    df = comparison_table(scene, outcomes)
    if args.wide:
        print(f"{scene.name}: end pose, final velocity; d_<source>: difference to a published result "
              "(heading wrapped; yaw turned: continuous, since the start)")
        print(_table_text(table_in(with_unit_headers(df), args.units)))
    else:
        print(f"{scene.name}: end poses (heading wrapped to (-180, 180]; turned: since the start)")
        poses = df[["source", "vehicle", "x", "y"]].assign(
            heading=df["heading"], yaw_turned=df["yaw_turned"],
            speed=np.hypot(df["vx"].astype(float), df["vy"].astype(float)),  # (vx, vy in km/h)
            at_rest=df["at_rest"], ok=df["ok"])
        print(_table_text(table_in(poses.rename(columns={"x": "x [m]", "y": "y [m]", "heading": "heading [deg]",
                                                         "yaw_turned": "turned [deg]", "speed": "v [km/h]"}),
                                   args.units)))
        refs = [c[2:-2] for c in df.columns if c.startswith("d_") and c.endswith("_m")]
        if refs:
            import pandas as pd
            print("differences to the published results (distance of the rest positions; heading: the model's "
                  "minus\nthe reference's)")
            models = df[df["ok"].notna()]
            rows = pd.concat([models[["source", "vehicle"]].assign(reference=ref, d_m=models[f"d_{ref}_m"],
                                                                    d_deg=models[f"d_{ref}_deg"]) for ref in refs])
            print(_table_text(table_in(rows.rename(columns={"source": "model", "d_m": "distance [m]",
                                                            "d_deg": "heading [deg]"}), args.units)))
    spread = model_spread(df, outcomes)
    if len(spread):
        print("spread between the models (the largest over every pair that ran; the choice of model is an\n"
              "uncertainty of its own)")
        print(_table_text(table_in(spread.rename(columns={"distance_m": "distance [m]", "distance_pair": "models apart",
                                                          "heading_deg": "heading [deg]",
                                                          "heading_pair": "models turned"}), args.units)))
    for m, out in outcomes.items():
        for w in out.warnings:
            print(f"warning ({m}):", w)
    for m in failed:
        print(f"crashlab: simulation failed: {args.scene}: model {m}: {'; '.join(outcomes[m].warnings)}",
              file=sys.stderr)
    return 3 if failed else 0
