"""`crashlab stiffness --side S --test MASS:SPEED:C1,...,Cn:WIDTH[:BARRIER_MASS] [--test ...] [--b0 KMH|fit]`: a
side's CRASH3 A and B from its crash tests, read from the command line; the fit in crashlab.stiffness
(docs/physics.md §28 "Stiffness from crash tests")."""
from __future__ import annotations

import json
import math
import re

from ..damage import crush_energy
from ..errors import InputError
from ..stiffness import CrashTest, default_b0, fit_stiffness
from ..structure import SOURCE_PATTERN
from ..units import kmh_to_ms
from .damage import parse_profile, vehicle_for


def parse_test(text: str, key: str, where: str = "command line") -> CrashTest:
    """'MASS:SPEED:C1,...,Cn:WIDTH[:BARRIER_MASS]' (kg, km/h, m, m, kg) as a CrashTest (checked by the fit)."""
    _text(text, key, where)
    parts = str(text).strip().split(":")
    if len(parts) not in (4, 5):
        raise InputError(where, key, f"MASS:SPEED:C1,...,Cn:WIDTH[:BARRIER_MASS] (kg, km/h, m, m, kg), got {text!r}")
    try:
        mass, speed, width = float(parts[0]), float(parts[1]), float(parts[3])
        barrier = float(parts[4]) if len(parts) == 5 else None
    except ValueError:
        raise InputError(where, key, f"MASS, SPEED, WIDTH and BARRIER_MASS are numbers (kg, km/h, m, kg), got "
                         f"{text!r}") from None
    return CrashTest(mass, kmh_to_ms(speed), tuple(parse_profile(parts[2], f"{key} profile", where)), width,
                     barrier, str(text).strip())


def _text(text: str, key: str, where: str = "command line") -> str:
    """The text of an option that goes into the printed table: no control characters (a vehicle file's source
    takes none) and encodable as UTF-8 (a byte that is not arrives as a lone surrogate)."""
    text = str(text)
    if not re.fullmatch(SOURCE_PATTERN, text.strip()):  # the vehicle file's own rule (crashlab.structure)
        raise InputError(where, key, "contains a control character (a vehicle file's source takes none)")
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        raise InputError(where, key, "is not UTF-8 text") from None
    return text


def _number(x: float) -> str:
    """A coefficient for the table: one decimal from 100 up, else six significant digits (no 0.0 for a small one)."""
    return f"{x:.1f}" if abs(x) >= 100.0 else f"{x:.6g}"


def command(side: str, tests: list[str], b0: str | None = None, restitution: float = 0.0, source: str = "",
            as_json: bool = False, vehicle: str | None = None) -> str:
    """What `crashlab stiffness` prints: A, B, G, the crash plot and each test's EBS against the fit's, and the
    vehicle file's [structure.<side>] table to paste (text), or the same as JSON. b0: km/h, "fit", or None for
    the side's class value (crashlab.structure.CRUSH_REFERENCE). `vehicle` (a library name or vehicle file): the
    EBS its present structure of the side gives each test's profile beside them."""
    if side not in ("front", "rear", "side"):
        raise InputError("command line", "--side", f"one of front, rear, side, got {side!r}")
    parsed = [parse_test(t, f"--test {k + 1}") for k, t in enumerate(tests or [])]
    if b0 is None:
        b0_ms = default_b0(side)
    elif str(b0).strip().lower() == "fit":
        b0_ms = None
    else:
        try:
            b0_ms = kmh_to_ms(float(b0))
        except ValueError:
            raise InputError("command line", "--b0", f"a speed in km/h or 'fit', got {b0!r}") from None
    fit = fit_stiffness(parsed, b0_ms, restitution, side=side)
    present = vehicle_for(vehicle, target_key="--vehicle").structure[side] if vehicle is not None else None
    if fit.b0_fitted:
        how = "b0 fitted"
    elif b0 is not None:
        how = f"b0 = {fit.b0 * 3.6:.2f} km/h given"
    else:
        how = f"b0 = {fit.b0 * 3.6:.2f} km/h, the class estimates' value for a {side}"
    src = _text(source, "--source").strip() or (f"crash plot of {len(parsed)} test(s) ("
                                                f"{'; '.join(t.label for t in parsed)}), {how}, restitution "
                                                f"{restitution:g} (crashlab stiffness, docs/physics.md §28)")
    src = src if src.startswith("derived") else f"derived: {src}"
    rep = {"side": side, "A": fit.A, "B": fit.B, "G": fit.G, "b0_kmh": fit.b0 * 3.6, "b1_per_s": fit.b1,
           "b0_fitted": fit.b0_fitted, "width": fit.width, "source": src,
           "tests": [{"test": t.label, "energy": e, "ebs_kmh": v * 3.6, "ebs_fit_kmh": f * 3.6,
                      "energy_fit": crush_energy(list(t.profile), t.width, fit.A, fit.B)}
                     for t, e, v, f in zip(parsed, fit.energies, fit.ebs, fit.ebs_fitted)],
           "warnings": list(fit.warnings)}
    if present is not None:
        rep["vehicle"] = {"name": vehicle, "A": present.A, "B": present.B, "width": present.width,
                          "source": present.source}
        for row, t in zip(rep["tests"], parsed):
            energy = crush_energy(list(t.profile), t.width, present.A, present.B)
            row["energy_vehicle"], row["ebs_vehicle_kmh"] = energy, math.sqrt(2.0 * energy / t.mass) * 3.6
    if as_json:
        return json.dumps(rep, indent=2)
    lines = [f"CRASH3 stiffness of the {side} from {len(parsed)} crash test(s) ({how}):",
             f"  A = {_number(fit.A)} N/m   B = {_number(fit.B)} N/m^2   G = A^2/2B = {_number(fit.G)} J/m",
             f"  crash plot EBS = b0 + b1 C: b0 = {fit.b0 * 3.6:.2f} km/h, b1 = {fit.b1:.3f} 1/s "
             f"(over {fit.width:g} m at the tests' mean mass {fit.mass:.0f} kg)", "",
             f"  {'test':<40} {'energy [J]':>11} {'EBS [km/h]':>11} {'fit [km/h]':>11}"
             + (f" {'now [km/h]':>11}" if present is not None else "")]
    for t in rep["tests"]:
        lines.append(f"  {t['test'][:40]:<40} {t['energy']:>11.0f} {t['ebs_kmh']:>11.2f} {t['ebs_fit_kmh']:>11.2f}"
                     + (f" {t['ebs_vehicle_kmh']:>11.2f}" if present is not None else ""))
    if present is not None:
        lines += ["", f"  now: {vehicle}'s {side}, A = {_number(present.A)} N/m, B = {_number(present.B)} N/m^2 over "
                  f"{present.width:g} m ({present.source[:70]}{'...' if len(present.source) > 70 else ''})"]
    lines += ["", "For the vehicle file:", "", f"[structure.{side}]", f"A = {_number(fit.A)}", f"B = {_number(fit.B)}",
              f"width = {fit.width:g}", f"source = {json.dumps(src, ensure_ascii=False)}"]
    lines += [f"warning: {w}" for w in fit.warnings]
    return "\n".join(lines)
