"""`crashlab vehicles`: the library's vehicles with their key numbers and the source of each."""
from __future__ import annotations

from importlib import resources
from pathlib import Path

from ..input_files import read_toml
from ..structure import Structure
from ..vehicle import VEHICLE_CLASSES, library, load_vehicle


def library_table() -> list[dict]:
    """The library's vehicles with their key numbers (SI), one dict each, sorted by class then mass:
    file (library name), name, class, mass, length, width, wheelbase, yaw_inertia, yaw_inertia_source
    ('measured', 'estimate' or 'published', by the start of the file's [sources] entry), source (the yaw
    inertia's entry), front_A [N/m], front_B [N/m^2] and structure_source ('class default' when the file has no
    [structure.front], else 'estimate' or 'published' by the start of its source)."""
    order = {c: i for i, c in enumerate(VEHICLE_CLASSES)}
    rows = []
    for ref in library():
        spec = load_vehicle(ref)
        path = Path(str(resources.files("crashlab").joinpath("vehicles", ref + ".toml")))
        data = read_toml(path, "vehicle")
        src = (data.get("sources") or {}).get("yaw_inertia", "")
        rows.append(dict(file=ref, name=spec.name, vehicle_class=data.get("class", ""), mass=spec.mass,
                         length=spec.length, width=spec.width, wheelbase=spec.wheelbase,
                         yaw_inertia=spec.yaw_inertia,
                         yaw_inertia_source=next((w for w in ("estimate", "measured")
                                                  if src.lower().startswith(w)), "published" if src else ""),
                         source=src, front_A=spec.structure["front"].A, front_B=spec.structure["front"].B,
                         structure_source=_structure_kind(spec.structure["front"])))
    rows.sort(key=lambda r: (order.get(r["vehicle_class"], len(order)), r["mass"], r["file"]))
    return rows


def _structure_kind(s: Structure) -> str:
    if s.default:
        return "class default"
    return "estimate" if s.source.lower().startswith("estimate") else "published"


def format_library_table(rows: list[dict] | None = None) -> str:
    """`crashlab vehicles`: one line per library vehicle, units in the header; the front's CRASH3 stiffness
    and whether it is the file's (estimate or published) or the class default (docs/physics.md §28)."""
    rows = library_table() if rows is None else rows
    head = (f"{'vehicle':<16} {'class':<9} {'mass [kg]':>9} {'length [m]':>10} {'width [m]':>9} "
            f"{'wheelbase [m]':>13} {'yaw inertia [kg m^2]':>20}  yaw inertia is  "
            f"{'front A [kN/m]':>14} {'B [kN/m^2]':>10}  front A, B are  name")
    lines = [head]
    for r in rows:
        lines.append(f"{r['file']:<16} {r['vehicle_class']:<9} {r['mass']:>9.1f} {r['length']:>10.3f} "
                     f"{r['width']:>9.3f} {r['wheelbase']:>13.3f} {r['yaw_inertia']:>20.1f}  "
                     f"{r['yaw_inertia_source']:<14}  {r['front_A'] / 1e3:>14.1f} {r['front_B'] / 1e3:>10.0f}  "
                     f"{r['structure_source']:<14}  {r['name']}")
    return "\n".join(lines)
