"""`crashlab bench`: simulations per second of a model, one at a time and in a batch."""
from __future__ import annotations

import math
import os
import platform
import time
from pathlib import Path


def default_scene_path() -> Path:
    """The bundled side collision (PC-Crash case 3), from the installed examples (crashlab.tools.examples)."""
    from .examples import path
    return path("pc_crash/side.toml")


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}"


def run_bench(model_name="impulse", scene_path=None, batch=1000, repeat=3):
    from ..registry import get_model
    from ..scene_file import load_scene
    scene = load_scene(scene_path or default_scene_path())
    model = get_model(model_name)
    model.simulate(scene)  # compile / warm up
    model.simulate_batch([scene] * 2)
    n_single = max(1, min(50, batch))
    best_single = min(_time(lambda: [model.simulate(scene) for _ in range(n_single)]) for _ in range(repeat))
    first = scene.vehicles[0]
    scenes = [scene.with_vehicle(first.name, speed=first.speed * (0.9 + 0.2 * k / batch))
              for k in range(batch)]
    # with and without the physics guard, interleaved so that both see the same machine load
    unguarded = type(model).simulate_batch.__wrapped__
    best_batch, best_bare = math.inf, math.inf
    for _ in range(repeat):
        best_batch = min(best_batch, _time(lambda: model.simulate_batch(scenes)))
        best_bare = min(best_bare, _time(lambda: unguarded(model, scenes)))
    # crashlab.simulate (registry look-up, option validation) against model.simulate, interleaved
    from .. import simulate
    best_api, best_direct = math.inf, math.inf
    for _ in range(repeat):
        best_direct = min(best_direct, _time(lambda: [model.simulate(scene) for _ in range(n_single)]))
        best_api = min(best_api, _time(lambda: [simulate(scene, model_name) for _ in range(n_single)]))
    print(f"machine: {machine()}")
    print(f"model {model_name}, scene {scene.name}")
    print(f"single:   {n_single / best_single:10.0f} simulations/s ({best_single / n_single * 1e3:.3f} ms each)")
    print(f"batch {batch}: {batch / best_batch:8.0f} simulations/s ({best_batch / batch * 1e3:.3f} ms each); "
          f"without the physics guard {batch / best_bare:.0f}/s "
          f"(guard costs {100 * (best_batch / best_bare - 1):.1f} %)")
    print(f"crashlab.simulate: {(best_api - best_direct) / n_single * 1e3:+.3f} ms a call over model.simulate")
    return n_single / best_single, batch / best_batch


def _time(fn):
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t
