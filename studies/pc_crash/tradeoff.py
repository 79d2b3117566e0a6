"""Cost against accuracy of every collision model on the thesis's three PC-Crash cases.

For each case and model: wall time per simulation (best of `--repeat`) and the rest-pose differences to
PC-Crash (mean distance [m], mean |heading difference| [deg]); writes a markdown table and a figure.
Run:  python studies/pc_crash/tradeoff.py [--models impulse,pymunk,multibody] [--out out/tradeoff]
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import crashlab
from crashlab.tools.compare import comparison_table

HERE = Path(__file__).resolve().parent
CASES = ["head_on", "offset", "side"]


def measure(models, repeat=3):
    rows = []
    for case in CASES:
        scene = crashlab.load_scene(HERE / f"{case}.toml")
        for name in models:
            model = crashlab.get_model(name)
            out = model.simulate(scene)  # warm-up (compilation)
            best = np.inf
            for _ in range(repeat):
                t = time.perf_counter()
                out = model.simulate(scene)
                best = min(best, time.perf_counter() - t)
            df = comparison_table(scene, {name: out})
            mine = df[df.source == name]
            rows.append({"case": case, "model": name, "ok": out.outcome_ok, "wall_time_s": best,
                         "distance_m": mine["d_pc_crash_m"].mean(),
                         "heading_deg": mine["d_pc_crash_deg"].abs().mean()})
    import pandas as pd
    return pd.DataFrame(rows)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--models", default=",".join(crashlab.available_models()))
    p.add_argument("--out", default="out/tradeoff")
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    df = measure([m for m in args.models.split(",") if m], args.repeat)
    print(df.to_string(index=False, float_format="{:.4g}".format))
    (out / "tradeoff.md").write_text(df.to_markdown(index=False, floatfmt=".4g") + "\n")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4))
    for name, g in df[df.ok].groupby("model"):
        ax.scatter(g.wall_time_s, g.distance_m, label=name)
        for _, r in g.iterrows():
            ax.annotate(r.case, (r.wall_time_s, r.distance_m), fontsize=7)
    ax.set_xscale("log")
    ax.set_xlabel("wall time per simulation [s]")
    ax.set_ylabel("mean rest-position difference to PC-Crash [m]")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "tradeoff.png", dpi=120)
    print(f"written: {out / 'tradeoff.md'}, {out / 'tradeoff.png'}")


if __name__ == "__main__":
    main()
