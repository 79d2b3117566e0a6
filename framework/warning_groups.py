"""The warnings of many runs (a Monte Carlo's draws, a study's variants) told once each, with how many runs gave them.

Runs of one scene give the same warning with other numbers in it (restitution = "speed" held at its end value
at a closing speed of 48.3 km/h in one draw, 52.1 km/h in the next, docs/physics.md §13b). A warning's kind is
its text with the numbers taken out; `group` finds the runs that gave each kind and writes it once, each
number that differs between the runs as its range ("closing speed 48.3 to 52.1 km/h"), in the order the kinds
first occur.

    group(runs)   [(text, indices of the runs that gave it)] for runs given as iterables of warnings
"""
from __future__ import annotations

import re
from collections.abc import Iterable

# unsigned (a sign or hyphen stays in the kind); not a name's digits (V1, barrier_2: another kind)
NUMBER = re.compile(r"(?<![A-Za-z_\d.])\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")


def group(runs: Iterable[Iterable[str]]) -> list[tuple[str, list[int]]]:
    """Each kind of warning (its text without numbers) once, with the indices of the runs that gave it (a run
    that gave it twice listed once) and its numbers as they were, or their range where the runs differ."""
    by_text: dict[str, list[int]] = {}  # each distinct text once (draws repeat texts): the runs that gave it
    for run, warnings in enumerate(runs):
        for w in warnings:
            which = by_text.setdefault(str(w), [])
            if not which or which[-1] != run:
                which.append(run)
    kinds: dict[tuple, dict] = {}
    for text, which in by_text.items():
        key = tuple(NUMBER.split(text))
        numbers = NUMBER.findall(text)
        g = kinds.setdefault(key, {"runs": set(), "low": list(numbers), "high": list(numbers)})
        g["runs"].update(which)
        for k, s in enumerate(numbers):
            if float(s) < float(g["low"][k]):
                g["low"][k] = s
            if float(s) > float(g["high"][k]):
                g["high"][k] = s
    out = []
    for key, g in kinds.items():
        shown = [lo if lo == hi else f"{lo} to {hi}" for lo, hi in zip(g["low"], g["high"])]
        out.append(("".join(part + (shown[k] if k < len(shown) else "") for k, part in enumerate(key)),
                    sorted(g["runs"])))
    return out
