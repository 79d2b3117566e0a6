"""`crashlab reconstruct STUDY`: load, run, print the Pareto set (or the JSON result) and a summary line."""
from __future__ import annotations

import json

from crashlab.errors import InputError
from crashlab.registry import UnknownPluginError, available_optimizers

from .study import load_study


def run_cli(args) -> int:
    """args: the parsed `crashlab reconstruct` options (crashlab.cli). Bad input raises InputError."""
    study = load_study(args.study)
    if study.spec.uncertain:
        raise InputError(args.study, "uncertain", "uncertain parameters are priors of `crashlab infer`; the search "
                         "does not take them yet (run `crashlab infer`, or remove them to search with the scene's "
                         "values)")
    if args.optimizer and args.optimizer not in available_optimizers():
        raise InputError(args.study, "--optimizer",
                         str(UnknownPluginError("optimizer", args.optimizer, available_optimizers())))
    res = study.run(optimizer=args.optimizer, workers=args.workers, scheduler=args.scheduler,
                    out_dir=args.out, resume=args.resume, progress=not (args.json or args.no_progress))
    if args.json:
        print(json.dumps(res.to_json_dict(), indent=2))
        return 0
    import pandas as pd
    with pd.option_context("display.float_format", "{:.3f}".format, "display.width", 200, "display.max_columns", 40):
        cols = [f.label for f in study.spec.free] + [f"f_{n}" for n in study.objective_names]
        cols += [f"dheading_{n}" for n, ev in study.evidence.items() if ev[2] is not None]
        print(res.pareto[cols].to_string(index=False) if len(res.pareto) else "no feasible solution")
    print(f"evaluations {res.evaluations}, failed {res.failed}, feasible {res.feasible_fraction:.1%}, "
          f"{res.wall_time_s:.2f} s" + (f", outputs in {args.out}" if args.out else ""))
    return 0
