"""`crashlab vehicles`: the library's vehicles with their key numbers, the structure of each side that can be
struck (CRASH3 A, B over a width, docs/physics.md §28) and whether each number is measured, published or an
estimate."""
from __future__ import annotations

import json
import textwrap
from importlib import resources
from pathlib import Path

from ..input_files import read_toml
from ..structure import STRUCTURE_SIDES, Structure
from ..vehicle import VEHICLE_CLASSES, library, load_vehicle

LINE_WIDTH = 120  # the printed tables fit this many columns (a long name wraps under its column)


def source_kind(source: str) -> str:
    """What a [sources] entry says of its number, by its start: 'measured', 'estimate', 'derived' (from
    measured values), 'published' (any other source text) or 'no source' (none given)."""
    text = source.strip().lower()
    if not text or text == "not given":  # crashlab.structure.structure_of's text for a side without one
        return "no source"
    return next((w for w in ("measured", "estimate", "derived") if text.startswith(w)), "published")


def _structure_record(s: Structure) -> dict:
    """One side's structure as `crashlab vehicles --json` gives it (SI)."""
    return dict(A=s.A, B=s.B, width=s.width, kind="class default" if s.default else source_kind(s.source),
                source=s.source)


def vehicle_record(path: Path, vehicle: str | None = None) -> dict:
    """The record of the vehicle file at `path` (SI), as `crashlab vehicles` shows it: vehicle (the name a scene
    writes; default the file's stem), name, class, mass [kg], length, width, wheelbase [m], yaw_inertia [kg m^2],
    yaw_inertia_kind and yaw_inertia_source (its [sources] entry; kinds: `source_kind`), and structure: side
    (front, rear, side) -> A [N/m], B [N/m^2], width [m] (the width over which they hold), kind ('class default'
    when the file has no [structure.<side>], else `source_kind` of its source) and source (its text)."""
    spec = load_vehicle(path.name, base_dir=path.parent)
    data = read_toml(path, "vehicle")
    src = (data.get("sources") or {}).get("yaw_inertia", "")
    return {"vehicle": vehicle or path.stem, "name": spec.name, "class": data.get("class", ""), "mass": spec.mass,
            "length": spec.length, "width": spec.width, "wheelbase": spec.wheelbase, "yaw_inertia": spec.yaw_inertia,
            "yaw_inertia_kind": source_kind(src), "yaw_inertia_source": src,
            "structure": {side: _structure_record(spec.structure[side]) for side in STRUCTURE_SIDES}}


def library_table() -> list[dict]:
    """The library's vehicles (`vehicle_record` each), sorted by class then mass."""
    order = {c: i for i, c in enumerate(VEHICLE_CLASSES)}
    rows = [vehicle_record(Path(str(resources.files("crashlab").joinpath("vehicles", ref + ".toml"))), ref)
            for ref in library()]
    rows.sort(key=lambda r: (order.get(r["class"], len(order)), r["mass"], r["vehicle"]))
    return rows


def format_vehicle_table(rows: list[dict]) -> str:
    """One row per vehicle: class, mass, size, wheelbase, yaw inertia and its kind, name (wrapped under its
    column beyond LINE_WIDTH)."""
    w = max([len("vehicle")] + [len(r["vehicle"]) for r in rows])
    cols = f"{'':<{w}} {'':<8} {'mass':>7} {'length':>6} {'width':>5} {'wheelbase':>9} {'yaw inertia':<18}"
    head = [cols.rstrip(),
            f"{'vehicle':<{w}} {'class':<8} {'[kg]':>7} {'[m]':>6} {'[m]':>5} {'[m]':>9} {'[kg m^2]':>8} "
            f"{'is':<9} name"]
    indent = len(cols) + 1
    lines = head
    for r in rows:
        prefix = (f"{r['vehicle']:<{w}} {r['class']:<8} {r['mass']:>7.1f} {r['length']:>6.3f} {r['width']:>5.3f} "
                  f"{r['wheelbase']:>9.3f} {r['yaw_inertia']:>8.1f} {r['yaw_inertia_kind']:<9} ")
        name = textwrap.wrap(r["name"], max(20, LINE_WIDTH - indent)) or [""]
        lines.append(prefix + name[0])
        lines += [" " * indent + part for part in name[1:]]
    return "\n".join(lines)


def format_structure_table(rows: list[dict]) -> str:
    """One row per vehicle and side that can be struck: CRASH3 A, B, the width they hold over and their kind
    (docs/physics.md §28); the sources' texts are in --json and the vehicle files."""
    w = max([len("vehicle")] + [len(r["vehicle"]) for r in rows])
    lines = [f"{'vehicle':<{w}} {'side':<5} {'A [kN/m]':>8} {'B [kN/m^2]':>10} {'width [m]':>9}  A, B are"]
    for r in rows:
        for side in STRUCTURE_SIDES:
            s = r["structure"][side]
            lines.append(f"{r['vehicle']:<{w}} {side:<5} {s['A'] / 1e3:>8.1f} {s['B'] / 1e3:>10.0f} "
                         f"{s['width']:>9.3f}  {s['kind']}")
    return "\n".join(lines)


def format_library_table(rows: list[dict] | None = None) -> str:
    """`crashlab vehicles`: the vehicle table, then the structure table (each within LINE_WIDTH columns)."""
    rows = library_table() if rows is None else rows
    return "\n".join([format_vehicle_table(rows), "",
                      "The structure of each side that can be struck (CRASH3, docs/physics.md section 28; both "
                      "flanks are 'side'):",
                      "A, B, the width they hold over, and whether they are published, an estimate or the class "
                      "default (the file has no",
                      "[structure.<side>]). `crashlab vehicles --json` gives every source's text.", "",
                      format_structure_table(rows)])


def library_json(rows: list[dict] | None = None) -> str:
    """`crashlab vehicles --json`: the list of `library_table` records (SI: kg, m, kg m^2, N/m, N/m^2)."""
    return json.dumps(library_table() if rows is None else rows, indent=2)
