"""Momentum balance of the pymunk model across a car-to-car impact, against the step size.

An oblique, eccentric impact of two cars with the ground forces off (`ground_forces=False`): nothing but
the contact acts, so linear momentum and the angular momentum about any fixed point must be conserved.
Chipmunk's contact impulses are equal and opposite (linear momentum is exact up to round-off), but its
friction impulses act on the two surface points of a penetrating contact, a penetration depth apart, so
angular momentum is not conserved exactly; the error shrinks with the step (the penetration is about
v dt). Because linear momentum is conserved, the change of angular momentum is the same about every fixed
point; it is reported relative to the angular momentum about the system's centre of mass (the smallest
magnitude any reference point gives, so the strictest relative error).

    python studies/pymunk/angular_momentum_vs_step.py
"""
import math
from pathlib import Path

import numpy as np

from crashlab.models.pymunk import PymunkModel
from crashlab.scene_file import load_scene

STEPS = (2e-3, 1e-3, 5e-4, 2.5e-4, 1e-4)


def oblique_scene(duration=0.5):
    return load_scene(Path(__file__).resolve().parent / "oblique.toml").replace(duration=duration)


def momenta(scene, states):
    """Linear momentum (px, py) and angular momentum about the origin of states (n, 6)."""
    p = np.zeros(2)
    L = 0.0
    for v, s in zip(scene.vehicles, states):
        m, iz = v.spec.mass, v.spec.yaw_inertia
        p += m * s[3:5]
        L += m * (s[0] * s[4] - s[1] * s[3]) + iz * s[5]
    return p, L


def balance(dt, scene=None, **options):
    """Relative errors (linear, angular) of the momentum balance across the impact, and the outcome."""
    scene = scene or oblique_scene()
    out = PymunkModel(dt=dt, ground_forces=False, **options).simulate(scene)
    s0 = np.array([[v.x, v.y, v.heading, v.speed * math.cos(v.heading), v.speed * math.sin(v.heading),
                    v.yaw_rate] for v in scene.vehicles])
    s1 = np.column_stack([out.rest_si, out.final_si])
    p0, L0 = momenta(scene, s0)
    p1, L1 = momenta(scene, s1)
    mass = sum(v.spec.mass for v in scene.vehicles)
    cm = sum(v.spec.mass * s0[i, 0:2] for i, v in enumerate(scene.vehicles)) / mass
    L0_cm = L0 - (cm[0] * p0[1] - cm[1] * p0[0])  # about the system's centre of mass
    return (float(np.linalg.norm(p1 - p0) / np.linalg.norm(p0)), abs(L1 - L0) / abs(L0_cm), out)


def main():
    print("dt [s]    linear momentum error    angular momentum error    max penetration [mm]   delta-V V1 [km/h]")
    for dt in STEPS:
        ep, eL, out = balance(dt)
        dv = out.impacts.delta_v.iloc[0] if len(out.impacts) else math.nan
        print(f"{dt:<9g} {ep:<24.2e} {100 * eL:<8.4f} %                {1e3 * out.diagnostics['max_penetration']:<8.3f}"
              f"               {dv:.3f}")


if __name__ == "__main__":
    main()
