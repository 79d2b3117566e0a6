"""How the derived numbers of published/tests.toml were obtained from NHTSA's published channels.

python studies/validation/nhtsa_pulse.py v10146.093 v10146.094 57.09
Each file is an NHTSA ASCII channel (two columns: time [s], acceleration [g], vehicle x). The offset is the
mean before time 0; the acceleration (g = 9.80665 m/s^2) is integrated (trapezoid) from the impact speed:
the rebound speed is the most negative velocity (end of contact), delta-V = impact speed + rebound speed,
the dynamic crush is the displacement where the velocity first reaches zero.
"""
import sys

import numpy as np

G = 9.80665


def pulse(path: str, v0_kmh: float) -> tuple[float, float, float]:
    d = np.loadtxt(path)
    t, a = d[:, 0], d[:, 1] * G
    a = a - a[t < 0].mean()
    t, a = t[t >= 0], a[t >= 0]
    v = v0_kmh / 3.6 + np.concatenate([[0.0], np.cumsum(0.5 * (a[1:] + a[:-1]) * np.diff(t))])
    x = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    rebound = -v.min() * 3.6
    return rebound, v0_kmh + rebound, float(x[np.argmax(v <= 0)])


if __name__ == "__main__":
    *files, v0 = sys.argv[1:]
    for f in files:
        r, dv, c = pulse(f, float(v0))
        print(f"{f}: rebound {r:.2f} km/h, delta-V {dv:.2f} km/h, dynamic crush {c:.3f} m")
