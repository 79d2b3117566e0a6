"""Command line: crashlab COMMAND, each command below with its --help.

Bad input exits with status 2 and one line naming the file, the key and the problem; a simulation that
failed (the model's own failure or a physics-guard violation) exits with status 3 and one line; a
reconstruction or posterior that finished without a feasible solution exits with status 4 and one line
(crashlab.errors).
"""
from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

from ..errors import EXIT_NO_FEASIBLE, InputError
from ..outdir import check_output_file
from ..registry import UnknownPluginError
from ..version import package_version
from .simulate import _get_model, check_seed, cmd_compare, cmd_simulate, refuse_other_kind


class HelpFormatter(argparse.HelpFormatter):
    """Every option's help ends with its default, unless the help already says it or there is none to show
    (a flag, an option that is off without a value)."""

    def _get_help_string(self, action):
        text = action.help or ""
        if (not action.option_strings or "default" in text or action.default in (None, False)
                or action.default is argparse.SUPPRESS):
            return text
        return text + " (default: %(default)s)"


class _StoreOnce(argparse._StoreAction):
    """argparse's store, refusing an option given twice: the last one won silently (a second --with dropped the
    first vehicle). The options given are marked in the namespace (GIVEN), which parse_args takes out again."""

    def __call__(self, parser, namespace, values, option_string=None):
        given = namespace.__dict__.setdefault(GIVEN, set())
        if option_string is not None and self.dest in given:
            parser.error(f"argument {'/'.join(self.option_strings)}: given twice; give it once")
        given.add(self.dest)
        super().__call__(parser, namespace, values, option_string)


GIVEN = "_options_given"


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are the project's one line (crashlab.errors): "crashlab: error: command
    line: KEY: problem (PROG --help)", exit 2, instead of argparse's usage and message; --help is unchanged; an
    option given twice is refused (_StoreOnce, every plain option's action). Its subcommands' parsers are of this
    class too (argparse makes them with the parent's class)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.register("action", None, _StoreOnce)
        self.register("action", "store", _StoreOnce)

    def error(self, message):
        key, problem = _key_and_problem(" ".join(str(message).split()))
        err = InputError("command line", key, f"{problem} ({self.prog} --help)")
        self.exit(2, f"crashlab: error: {err}\n")

    def parse_args(self, args=None, namespace=None):
        """argparse's parse_args, with the unknown arguments refused by the parser of their command (its
        --help lists the options they are not)."""
        args, extra = self.parse_known_args(args, namespace)
        vars(args).pop(GIVEN, None)
        if extra:
            command = getattr(args, "command", None)
            sub = _subparsers(self).get(command, self)
            sub.error(f"unrecognized arguments: {' '.join(extra)}")
        return args


def _subparsers(parser) -> dict:
    """name -> parser of each subcommand of `parser` (none: {})."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


# argparse's messages -> (key, problem) of the one error line
_ARGPARSE_MESSAGES = (
    (re.compile(r"^argument (?P<key>[^:]+): (?P<problem>.*)$"), "{problem}"),
    (re.compile(r"^the following arguments are required: (?P<key>.*)$"), "required"),
    (re.compile(r"^unrecognized arguments: (?P<key>.*)$"), "not an option of this command"),
    (re.compile(r"^ambiguous option: (?P<key>\S+) could match (?P<problem>.*)$"), "ambiguous: could match {problem}"),
)


def _key_and_problem(message: str) -> tuple[str, str]:
    """(key, problem) of an argparse error message: the argument it names and what is wrong with it; a message of
    another shape keeps its text under the key "arguments"."""
    for pattern, problem in _ARGPARSE_MESSAGES:
        m = pattern.match(message)
        if m:
            return m["key"], problem.format(**m.groupdict())
    return "arguments", message


def cmd_vehicles(args):
    from .vehicles import format_library_table, library_json
    print(library_json() if args.json else format_library_table())
    return 0


def _shown(value) -> str:
    """An option's default as a file writes it: true/false for a boolean (not 1/0)."""
    return str(value).lower() if isinstance(value, bool) else str(value)


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
        print(tabulate([[r["name"], r["type"], r["unit"], _shown(r["default"]), r["range"], r["accuracy"],
                         r["description"]] for r in rows],
                       headers=["option", "type", "unit", "default", "range", "accuracy", "meaning"],
                       tablefmt="simple", maxcolwidths=[None, None, None, None, None, None, 60],
                       disable_numparse=True))
        return 0
    print("models:     " + ", ".join(available_models()))
    print("optimizers: " + ", ".join(available_optimizers()))
    return 0


def cmd_bench(args):
    from ..tools.bench import run_bench
    if args.scene is not None:
        if not args.scene:
            raise InputError("command line", "--scene", "an empty path; give a scene file (or no --scene: the "
                             "bundled side collision)")
        refuse_other_kind(args.scene, "scene", "bench takes")
    _get_model(args.model, args.scene or "crashlab bench")
    for option, value in (("--batch", args.batch), ("--repeat", args.repeat)):
        if value < 1:
            raise InputError("command line", option, f"must be at least 1, got {value}")
    run_bench(args.model, args.scene, args.batch, args.repeat)
    return 0


def cmd_damage(args):
    """`crashlab damage`: CRASH3 crush energy, EES and delta-V from a crush profile (crashlab.damage)."""
    from .damage import command
    print(command(args.target, args.side, args.profile, args.width, args.offset, args.pdof, args.vehicle,
                  args.other, args.restitution, args.json))
    return 0


def cmd_stiffness(args):
    """`crashlab stiffness`: a side's CRASH3 A and B from its crash tests (crashlab.stiffness)."""
    from .stiffness import command
    print(command(args.side, args.test, args.b0, args.restitution, args.source, args.json, args.vehicle))
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
        raise InputError("command line", "--runs", f"must be at least 0, got {args.runs}")
    check_seed(args.seed)
    if args.csv is not None:  # refused before the sweep, not after it
        check_output_file(args.csv, "--csv")
    df = stress.sweep(model, stress.random_scenes(args.runs, args.seed) + stress.extreme_scenes())
    if args.csv is not None:
        try:
            Path(args.csv).parent.mkdir(parents=True, exist_ok=True)
            df.to_csv(args.csv, index=False)
        except OSError as err:
            raise InputError(args.csv, "--csv", f"cannot write there ({err.strerror or err})") from None
        print(f"wrote {args.csv}", file=sys.stderr)
    s = stress.summary(df)
    print(f"model {args.model}: {s['runs']} runs (seed {args.seed}, + {len(stress.extreme_scenes())} extremes), "
          f"{s['caught']} caught by the guard or failed: {s['by_kind'] or 'none'}; "
          f"{s['moving_at_end']} with a vehicle moving at the end, {s['rolled_over']} rolled over")
    for _, r in df[~df.ok].iterrows():
        print(f"  {r.scene} ({r.speeds_kmh} km/h, {r.masses_kg} kg, {r.wheels}): {r.reason}")
    return 0


def _with_pdf(run, args):
    """run(args), and with --pdf DIR/report.pdf printed from DIR/report.html; a PDF that cannot be written
    (no --out, WeasyPrint missing) is refused before the run."""
    if not getattr(args, "pdf", False):
        return run(args)
    from pathlib import Path

    from crashlab.reconstruction.html_report import REPORT_NAME, check_pdf, write_pdf
    check_pdf(args.study, args.out)
    code = run(args)
    if code in (0, EXIT_NO_FEASIBLE) and (Path(args.out) / REPORT_NAME).is_file():
        print(f"wrote {write_pdf(Path(args.out) / REPORT_NAME)}", file=sys.stderr)
    return code


def cmd_reconstruct(args):
    from crashlab.reconstruction import run_cli
    refuse_other_kind(args.study, "study")
    return _with_pdf(run_cli, args)


def cmd_infer(args):
    from crashlab.reconstruction.command import cmd_infer as run
    refuse_other_kind(args.study, "study")
    return _with_pdf(run, args)


def cmd_avoid(args):
    from crashlab.reconstruction.command import cmd_avoid as run
    refuse_other_kind(args.study, "study")
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


def _run_options(parser) -> None:
    """--no-progress, --pdf and --units of a command that runs a search or a sampler and writes a report."""
    parser.add_argument("--no-progress", action="store_true", help="no progress line")
    parser.add_argument("--pdf", action="store_true", help="with --out: also print DIR/report.html to DIR/report.pdf "
                        "(A4; needs WeasyPrint: pip install \"crashlab[pdf]\")")
    _units_option(parser)


def _table_options(parser, wide: str) -> None:
    """--wide (what it adds: `wide`) and --units of a command that prints tables."""
    parser.add_argument("--wide", action="store_true", help=wide)
    _units_option(parser)


def _units_option(parser) -> None:
    """--units of a command that prints tables or writes files: what it shows, never what it computes."""
    parser.add_argument("--units", choices=("si", "us"), default=None,
                        help="units of every printed table, JSON, CSV file, figure and report: si (m, km/h, kg, J) "
                        "or us (ft, mph, lb, ft-lbf); degrees and seconds as they are (default: the scene's or "
                        "study's own, us where it says units = \"us\", else si)")


def _file_units(args) -> str:
    """--units when it is not given: the unit system the command's scene or study file is written in (a study
    in mph shows mph: its posterior.csv in km/h read as mph was a factor 1.6 off, a probe of 2026-11-28), si
    for a command without one."""
    from pathlib import Path

    from ..file_units import system_of
    from ..input_files import read_toml
    path = getattr(args, "scene", None) or getattr(args, "study", None)
    try:
        readable = bool(path) and Path(path).is_file()
    except OSError:  # a name the system refuses (too long)
        readable = False
    if not readable:
        return "si"  # (the command's own check names the path's problem)
    return system_of(read_toml(Path(path), "file"), path)


def build_parser():
    p = OneLineParser(prog="crashlab", description=__doc__.splitlines()[0], formatter_class=HelpFormatter)
    p.add_argument("--version", action="version", version=f"crashlab {package_version()}",
                   help="print the installed version and exit")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def command(name, help):
        return sub.add_parser(name, help=help, description=help, formatter_class=HelpFormatter)

    mo = command("models", "list the registered collision models and optimizers")
    mo.add_argument("--options", metavar="NAME", help="list the options of model NAME with unit, range, default "
                    "and accuracy direction (without it: the names of every model and optimizer)")
    mo.set_defaults(fn=cmd_models)
    ve = command("vehicles", "list the vehicle library: class, mass, size, wheelbase, yaw inertia, the CRASH3 "
                 "structure (A, B, width) of the front, rear and side, and whether each is measured, published or "
                 "an estimate")
    ve.add_argument("--json", action="store_true", help="print one JSON list of the vehicles (SI), with the "
                    "source text of the yaw inertia and of each side's structure")
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
    # (None unless given: refused without --animate; the defaults are cmd_simulate's)
    s.add_argument("--fps", type=float, default=None, help="--animate: frames per second of playback (default: "
                   "25.0)")
    s.add_argument("--slow-motion", type=float, default=None, metavar="FACTOR",
                   help="--animate: play FACTOR times slower than real time (at most 300 frames: a long run "
                   "plays faster) (default: 1.0)")
    s.add_argument("--monte-carlo", type=int, default=None, metavar="N",
                   help="draw the scene's [[uncertain]] parameters N times and simulate each draw (default: "
                   "one run of the nominal scene)")
    s.add_argument("--seed", type=int, default=None, help="--monte-carlo: seed of the draws (default: 1)")
    s.add_argument("--out", default=None, metavar="DIR", help="--monte-carlo: write montecarlo.csv, summary.csv "
                   "and montecarlo.png here (default: print the summary only)")
    s.add_argument("--timeout", type=float, default=None, metavar="SECONDS",
                   help="fail a run longer than SECONDS (exit 3): the run in a worker process, stopped when it "
                   "overruns (default: no limit)")
    _table_options(s, "print every column of the impact table (default: the columns that fit 100)")
    s.set_defaults(fn=cmd_simulate)
    c = command("compare", "compare models with each other and with the scene's published results")
    c.add_argument("scene", help="scene TOML file, optionally with [reference.SOURCE.VEHICLE] tables")
    c.add_argument("--models", default="impulse", metavar="A,B", help="comma-separated model names")
    c.add_argument("--json", action="store_true", help="print JSON instead of the table: {scene, results (one per "
                   "model), references, comparison, units}")
    c.add_argument("--plot", metavar="FILE", help="write one top view with every model's paths and end poses and "
                   "the published rest poses (PNG, PDF, SVG)")
    _table_options(c, "print every column in one table (default: end poses, then the differences to each "
                   "published result, within 100 columns)")
    c.set_defaults(fn=cmd_compare)
    b = command("bench", "simulations per second, single and batched")
    b.add_argument("--model", default="impulse", help="collision model")
    b.add_argument("--scene", default=None, help="scene file (default: the bundled side collision)")
    b.add_argument("--batch", type=int, default=1000, help="scenes per batched call")
    b.add_argument("--repeat", type=int, default=3, help="timed repetitions (the best one counts)")
    b.set_defaults(fn=cmd_bench)
    d = command("damage", "CRASH3 crush energy, EES and delta-V from a measured crush profile (docs/physics.md)")
    d.add_argument("target", metavar="SCENE|VEHICLE", help="a scene file (with --vehicle) or a vehicle name/file")
    d.add_argument("--side", required=True, choices=["front", "rear", "left", "right", "side"],
                   help="the damaged side (side, with --pdof: the flank the PDOF points at)")
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
    st = command("stiffness", "a side's CRASH3 stiffness A, B from its crash tests (Campbell's crash plot; "
                 "docs/physics.md)")
    st.add_argument("--side", required=True, choices=["front", "rear", "side"], help="the side the tests crushed")
    st.add_argument("--test", action="append", required=True, metavar="MASS:SPEED:C1,..,Cn:WIDTH[:BARRIER_MASS]",
                    help="one crash test: test mass [kg], impact speed [km/h], residual crush profile [m] (2, 4 or "
                    "6 points) over the crush width [m]; a rigid moving barrier's mass [kg] (default: a fixed "
                    "rigid barrier); repeat for more tests")
    st.add_argument("--b0", default=None, metavar="KMH|fit", help="the no-damage speed [km/h], or `fit` (two or "
                    "more tests); default the class estimates' value (front, rear 7.9 km/h; side 3.2 km/h)")
    st.add_argument("--restitution", type=float, default=0.0, help="the tests' restitution: the crush energy is "
                    "(1 - e^2) of the closing motion's (default 0, the crash plot's convention)")
    st.add_argument("--source", default="", help="the source text of the table printed (default: the tests)")
    st.add_argument("--vehicle", default=None, help="a library vehicle or vehicle file: the EBS its present "
                    "structure of the side gives each test's profile, beside the fit's")
    st.add_argument("--json", action="store_true", help="print JSON")
    st.set_defaults(fn=cmd_stiffness)
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
    _run_options(inf)
    inf.set_defaults(fn=cmd_infer)
    av = command("avoid", "would it have been avoided: the study's [[counterfactuals]] answered on the draws of an "
                 "earlier `crashlab infer STUDY --out DIR`")
    av.add_argument("study", help="study TOML file with [[counterfactuals]]")
    av.add_argument("--out", required=True, metavar="DIR", help="the infer run's output folder (posterior.csv); "
                    "counterfactuals.csv is written there")
    _units_option(av)
    av.set_defaults(fn=cmd_avoid)
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
    _run_options(r)
    r.set_defaults(fn=cmd_reconstruct)
    sd = command("study", "comparison studies of the models: run time against error, stability, scaling, "
                 "validation, the PC-Crash cases with every impulse law")
    sd.add_argument("name", help="workprecision | stability | scaling | validation | pc_crash | all")
    sd.add_argument("--models", default=None, help="comma-separated model names (default: every registered model)")
    sd.add_argument("--quick", action="store_true", help="a small configuration (minutes, not hours)")
    sd.add_argument("--out", required=True, metavar="DIR", help="folder for the CSV files and figures; required")
    _units_option(sd)
    sd.set_defaults(fn=cmd_study)
    sc = command("schema", "print the JSON Schema of a scene, study or vehicle file (for editors' completion and "
                 "checking), or with --markdown the reference of every key (docs/reference.md)")
    sc.add_argument("kind", nargs="?", choices=["scene", "study", "vehicle"], help="the file kind")
    sc.add_argument("--markdown", action="store_true", help="print docs/reference.md: every key of the three file "
                    "kinds with type, unit, range, default and meaning")
    sc.set_defaults(fn=cmd_schema)
    return p


# options whose value may start with "-" (a negative crush depth, offset or PDOF): argparse takes "-0.1,0.2" or
# "-1e1" (its negative-number test knows no exponent) for an option and prints its usage; glued to the option
# ("--profile=-0.1,0.2") the value reaches crashlab.damage, which takes it or refuses it in one line naming the key
DASH_VALUE_OPTIONS = ("--profile", "--with", "--offset", "--pdof", "--width", "--restitution")


def _glue_dash_values(argv: list[str]) -> list[str]:
    out, i = [], 0
    while i < len(argv):
        # an option argparse would take: one of them or an abbreviation of one (argparse's allow_abbrev)
        named = argv[i].startswith("--") and len(argv[i]) > 2 and any(o.startswith(argv[i]) for o in DASH_VALUE_OPTIONS)
        if named and i + 1 < len(argv) and argv[i + 1][:1] == "-" and argv[i + 1][1:2] in tuple("0123456789.,"):
            out.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
            continue
        out.append(argv[i])
        i += 1
    return out


# options naming a file or folder to write: an empty one would be no file at all, or the current folder
PATH_OPTIONS = {"out": "--out", "plot": "--plot", "csv": "--csv", "animate": "--animate"}


def main(argv=None):
    args = build_parser().parse_args(_glue_dash_values(sys.argv[1:] if argv is None else list(argv)))
    try:
        for dest, option in PATH_OPTIONS.items():
            if getattr(args, dest, None) == "":
                raise InputError("command line", option, "an empty path; give a file or folder name")
        if hasattr(args, "units") and args.units is None:
            args.units = _file_units(args)
        from ..outdir import lock_out_dir
        with lock_out_dir(getattr(args, "out", None), args.command):  # one writer per --out folder
            return args.fn(args)
    except InputError as err:
        print(f"crashlab: error: {err}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        return 0
