"""The reconstruction's commands: `crashlab reconstruct STUDY` (load, run, print the Pareto set or the JSON result
and a summary line), `crashlab infer STUDY --out DIR` (the posterior: crashlab.reconstruction.infer) and
`crashlab avoid STUDY --out DIR` (the counterfactuals on an infer run's draws). `--units us` shows every printed
table, CSV file, JSON and report in US units (crashlab.units, shown units: Study.shown_units); the computation
stays in file units."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from crashlab.errors import EXIT_NO_FEASIBLE, InputError
from crashlab.registry import UnknownPluginError, available_optimizers
from crashlab.units import json_in, table_in, unit_in, value_in

from .problem import variable_unit
from .schema import SEED_MAX
from .study import load_study


def run_cli(args) -> int:
    """args: the parsed `crashlab reconstruct` options (crashlab.cli). Bad input raises InputError."""
    study = load_study(args.study)
    study.shown_units = args.units
    if args.optimizer and args.optimizer not in available_optimizers():
        raise InputError(args.study, "--optimizer",
                         str(UnknownPluginError("optimizer", args.optimizer, available_optimizers())))
    res = study.run(optimizer=args.optimizer, workers=args.workers, scheduler=args.scheduler,
                    out_dir=args.out, resume=args.resume, progress=not (args.json or args.no_progress),
                    started=lambda: study_notes(args.study, study))
    refined = getattr(res, "refine", None)
    if args.json:
        out = json_in(res.to_json_dict(), args.units)
        if refined is not None:
            out["refine"] = refined.to_json_dict(args.units)
        print(json.dumps(out, indent=2))
        return _no_feasible(args, res)
    import pandas as pd
    with pd.option_context("display.float_format", _three_decimals, "display.width", 200, "display.max_columns", 40):
        cols = [f.label for f in study.variables] + [f"f_{n}" for n in study.objective_names]
        cols += [f"dheading_{n}" for n, ev in study.evidence.items() if ev[2] is not None]
        f_unit = "m" if study.mode == "thesis" else "sigma"  # misfit: residuals in their sigmas
        units = {f.label: variable_unit(f) for f in study.variables} | {c: f_unit for c in cols if c.startswith("f_")}
        header = {c: f"{c} [{units.get(c, 'deg')}]" if units.get(c, "deg") else c for c in cols}
        print(table_in(res.pareto[cols].rename(columns=header), args.units).to_string(index=False)
              if len(res.pareto) else "no feasible solution")
    print(f"evaluations {res.evaluations}, failed {res.failed}, feasible {res.feasible_fraction:.1%}, "
          f"{res.wall_time_s:.2f} s" + (f", outputs in {args.out}" if args.out else ""))
    if refined is not None:
        print(refined.summary_line(study.variables, wrote=bool(args.out), system=args.units))
    for w in getattr(res, "report_warnings", ()):  # summary.md's warnings (Pareto row 0's run, ...), also here
        print("crashlab: warning: " + w.replace("**", "").removeprefix("Warning").lstrip(": "), file=sys.stderr)
    return _no_feasible(args, res)


def study_notes(path, study, infer: bool = False) -> None:
    """The study's notes and evidence warnings on stderr, once the run starts (Study.run's and run_posterior's
    `started`): bad input found before it (options, checkpoint, scheduler) stays its one error line. Its
    [[questions]] and [[counterfactuals]], which only infer answers, are noted by reconstruct."""
    for note in study.notes:  # which bounds a free and uncertain field keeps, a setting a free field replaces
        print(f"crashlab: note: {path}: {note}", file=sys.stderr)
    for key, n in (("questions", len(study.questions)), ("counterfactuals", len(study.counterfactuals))):
        if n and not infer:  # checked when loaded (study.py), answered from a posterior only: not dropped in silence
            print(f"crashlab: note: {path}: {key}: {n} [[{key}]] checked, not answered by reconstruct: "
                  "crashlab infer answers them from the posterior's draws", file=sys.stderr)
    evidence_warnings(path, study)


def evidence_warnings(path, study) -> None:
    """Each evidence item's warnings on stderr, one line each (a damage profile without residual crush, a PDOF
    beyond the correction's limit, a sigma outside the first order: docs/physics.md §28); summary.md repeats them."""
    for it in getattr(study.evidence_set, "items", None) or ():
        for w in getattr(it, "warnings", ()):
            print(f"crashlab: warning: {path}: evidence.{it.label}: {w}", file=sys.stderr)


def _three_decimals(v: float) -> str:
    """A printed number with 3 decimals, 0.000 rather than -0.000."""
    text = f"{v:.3f}"
    return "0.000" if text == "-0.000" else text


def _never_scored(evidence_set, arch: dict) -> str:
    """The keys `evidence.damage.V.side` of the damage items no evaluation that ran could score (their residuals
    never finite), "evidence.damage.<vehicle>.side" where none can be told."""
    keys = []
    if evidence_set is not None and len(arch["X"]):
        R = np.asarray(arch["R"], dtype=float).reshape(len(arch["X"]), -1)[arch["ok"].astype(bool)]
        for it, cols in zip(evidence_set.items, evidence_set.item_slices()):
            if it.kind == "damage" and not np.isfinite(R[:, cols]).all(axis=1).any():
                keys.append(f"evidence.damage.{it.vehicles[0]}.side ({it.side})")
    return " and ".join(keys) or "evidence.damage.<vehicle>.side"


def _no_feasible(args, res) -> int:
    """EXIT_NO_FEASIBLE with one line on stderr when the run found no feasible solution, or none whose evidence
    could be scored (problem.scored_feasible: e.g. damage evidence on a side no run struck, docs/physics.md §28;
    not the objectives' size, a real misfit may be as large), else 0."""
    from .problem import scored_feasible
    arch = res.problem.archive_arrays()
    if len(res.pareto) and not scored_feasible(arch).any():
        print(f"crashlab: no feasible solution: {args.study}: none of {res.evaluations} evaluations could be scored "
              "on every evidence item (damage evidence needs an impact on the damaged side: check "
              f"{_never_scored(res.problem.evidence_set, arch)}; report.html with --out names the side Pareto row 0 "
              "struck)", file=sys.stderr)
        return EXIT_NO_FEASIBLE
    if len(res.pareto):
        return 0
    print(f"crashlab: no feasible solution: {args.study}: none of {res.evaluations} evaluations collided without a "
          f"start overlap and ended at rest ({res.failed} failed; their reasons in failures.csv and report.html "
          "with --out)", file=sys.stderr)
    return EXIT_NO_FEASIBLE


def cmd_infer(args) -> int:
    """`crashlab infer` (its options: crashlab.cli): the posterior (crashlab.reconstruction.infer.run_posterior),
    a line per variable (median, 90 % interval, ESS) in the shown units; bad input raises InputError (the CLI
    prints its one line and exits 2), no draw that explains the evidence exits EXIT_NO_FEASIBLE."""
    from .infer import run_posterior
    from .infer_report import chain_warnings, number
    from .posterior import load_posterior
    post = load_posterior(args.study)
    post.study.shown_units = args.units
    if args.samples is not None and not 10 <= args.samples <= 10_000_000:
        raise InputError(args.study, "--samples", f"{args.samples} is outside [10, 10000000]")
    if args.seed is not None and not 0 <= args.seed <= SEED_MAX:
        raise InputError(args.study, "--seed", f"{args.seed} is outside [0, {SEED_MAX}]")
    res = run_posterior(post, args.out, args.samples, args.seed, args.resume, args.workers,
                        progress=not getattr(args, "no_progress", False),
                        started=lambda: study_notes(args.study, post.study, infer=True))  # bad input: one line
    lo, med, hi = res.interval()
    for j, v in enumerate(post.variables):
        unit = unit_in(v.unit, args.units)
        lab = f"{v.label} [{unit}]" if unit and unit != "-" else v.label
        lo_j, med_j, hi_j = (value_in(q[j], v.unit, args.units) for q in (lo, med, hi))
        print(f"{lab:24s} {med_j:10.3f}  90 % [{lo_j:.3f}, {hi_j:.3f}]  ESS {number(res.ess[j], 0)}")
    print(f"{len(res.samples)} samples, {res.evaluations} model evaluations, {res.wall_time_s:.1f} s, "
          f"outputs in {args.out}")
    if res.refine is not None:
        print(res.refine.summary_line(post.study.variables, wrote=True, system=args.units))
    if res.counterfactuals:
        from . import counterfactual
        for line in counterfactual.summary_lines(res.counterfactuals, args.units):
            print(line)
    for w in chain_warnings(res):  # (summary.md has them too)
        print("warning: " + w.removeprefix("**Warning**: "), file=sys.stderr)
    for w in getattr(res, "model_warnings", ()):  # the median draw's run (infer_report.write_outputs)
        print("warning (the median draw's run): " + w, file=sys.stderr)
    if not np.isfinite(res.log_likelihood).any():
        print(f"crashlab: no feasible solution: {args.study}: no draw explains the evidence (every log-posterior "
              "is -inf: no contact, a failed run or a vehicle moving at the end; see summary.md)", file=sys.stderr)
        return EXIT_NO_FEASIBLE
    return 0


def cmd_avoid(args) -> int:
    """`crashlab avoid STUDY --out DIR`: the study's [[counterfactuals]] answered on DIR/posterior.csv, the draws
    of an earlier `crashlab infer STUDY --out DIR` (in either units: a column named with a US unit is read back
    into file units; crashlab.reconstruction.counterfactual): DIR/counterfactuals.csv and its figures
    (crashlab.reconstruction.avoidance), a line each on the terminal, in the shown units."""
    import pandas as pd

    from crashlab.units import table_from_shown

    from . import counterfactual
    from .avoidance import write_counterfactual_figures
    from .posterior import load_posterior
    post = load_posterior(args.study)
    post.study.shown_units = args.units
    if not post.counterfactuals:
        raise InputError(args.study, "counterfactuals", "the study has no [[counterfactuals]] to answer")
    path = Path(args.out) / "posterior.csv"
    try:
        table = table_from_shown(pd.read_csv(path))
    except (OSError, ValueError) as err:
        raise InputError(path, "--out", f"no posterior to read ({err}); run crashlab infer STUDY --out DIR first") \
            from None
    answers = counterfactual.run(post, counterfactual.posterior_draws(table, post.labels, path), args.out)
    for line in counterfactual.summary_lines([a.row for a in answers], args.units):
        print(line)
    figures, notes = write_counterfactual_figures(answers, post.study.scene.vehicle_names, args.out, args.units)
    for note in notes:
        print("warning: " + note, file=sys.stderr)
    for name, _ in figures:
        print(f"wrote {path.parent / name}", file=sys.stderr)
    print(f"wrote {path.parent / 'counterfactuals.csv'}", file=sys.stderr)
    return 0
