"""The comparison studies (`crashlab study NAME`): run time against error, numerical stability, scaling
with the size of the work, validation against published tests, the thesis's PC-Crash cases with every
impulse law and point-of-impact placement; for every registered model, plugins
included (they declare their accuracy knobs in their option schemas, crashlab.options).

Each study is a module with `run(models, out, quick) -> Path` that writes its CSV (the contract) and its
figures into `out` and records a model that fails on a cell as failed for that cell.
"""
STUDIES = ("workprecision", "stability", "scaling", "validation", "pc_crash")
