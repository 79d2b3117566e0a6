"""`crashlab study NAME [--models a,b] [--quick] [--units si|us] --out DIR`."""
from __future__ import annotations

import importlib

from crashlab.errors import InputError

from . import STUDIES
from .base import output_dir, resolve_models


def run_cli(args) -> int:
    names = list(STUDIES) if args.name == "all" else [args.name]
    if args.name != "all" and args.name not in STUDIES:
        raise InputError("command line", "study", f"unknown study {args.name!r}; known: "
                         f"{', '.join(STUDIES)}, all")
    if args.models is not None and not [m for m in args.models.split(",") if m.strip()]:
        raise InputError("command line", "--models", "give at least one model name (or no --models: every model)")
    models = resolve_models(args.models)
    out = output_dir(args.out)
    for name in names:
        module = importlib.import_module(f"crashlab.comparison.{name}")
        path = module.run(models, out, quick=args.quick, system=args.units)  # CSV, markdown, figures shown
        print(f"{name}: {path}")
    if args.name == "all":
        from .report import write_report
        print(f"report: {write_report(out, system=args.units)}")
    return 0
