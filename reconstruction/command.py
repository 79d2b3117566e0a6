"""`crashlab reconstruct STUDY`: load, run, print the Pareto set (or the JSON result) and a summary line."""
from __future__ import annotations

import json
import sys

from crashlab.errors import EXIT_NO_FEASIBLE, InputError
from crashlab.registry import UnknownPluginError, available_optimizers

from .problem import variable_unit
from .study import load_study


def run_cli(args) -> int:
    """args: the parsed `crashlab reconstruct` options (crashlab.cli). Bad input raises InputError."""
    study = load_study(args.study)
    for note in study.notes:  # a field both free and uncertain: which bounds apply (study.free_and_uncertain)
        print(f"crashlab: note: {args.study}: {note}", file=sys.stderr)
    if args.optimizer and args.optimizer not in available_optimizers():
        raise InputError(args.study, "--optimizer",
                         str(UnknownPluginError("optimizer", args.optimizer, available_optimizers())))
    res = study.run(optimizer=args.optimizer, workers=args.workers, scheduler=args.scheduler,
                    out_dir=args.out, resume=args.resume, progress=not (args.json or args.no_progress))
    refined = getattr(res, "refine", None)
    if args.json:
        out = res.to_json_dict()
        if refined is not None:
            out["refine"] = refined.to_json_dict()
        print(json.dumps(out, indent=2))
        return _no_feasible(args, res)
    import pandas as pd
    with pd.option_context("display.float_format", _three_decimals, "display.width", 200, "display.max_columns", 40):
        cols = [f.label for f in study.variables] + [f"f_{n}" for n in study.objective_names]
        cols += [f"dheading_{n}" for n, ev in study.evidence.items() if ev[2] is not None]
        f_unit = "m" if study.mode == "thesis" else "sigma"  # misfit: residuals in their sigmas
        units = {f.label: variable_unit(f) for f in study.variables} | {c: f_unit for c in cols if c.startswith("f_")}
        header = {c: f"{c} [{units.get(c, 'deg')}]" if units.get(c, "deg") else c for c in cols}
        print(res.pareto[cols].rename(columns=header).to_string(index=False) if len(res.pareto)
              else "no feasible solution")
    print(f"evaluations {res.evaluations}, failed {res.failed}, feasible {res.feasible_fraction:.1%}, "
          f"{res.wall_time_s:.2f} s" + (f", outputs in {args.out}" if args.out else ""))
    if refined is not None:
        print(refined.summary_line(study.variables, wrote=bool(args.out)))
    return _no_feasible(args, res)


def _three_decimals(v: float) -> str:
    """A printed number with 3 decimals, 0.000 rather than -0.000."""
    text = f"{v:.3f}"
    return "0.000" if text == "-0.000" else text


def _no_feasible(args, res) -> int:
    """EXIT_NO_FEASIBLE with one line on stderr when the run found no feasible solution, else 0."""
    if len(res.pareto):
        return 0
    print(f"crashlab: no feasible solution: {args.study}: none of {res.evaluations} evaluations collided without a "
          f"start overlap and ended at rest ({res.failed} failed; their reasons in failures.csv and report.html "
          "with --out)", file=sys.stderr)
    return EXIT_NO_FEASIBLE
