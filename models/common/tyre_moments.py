"""The UA tyre's moments about the wheel's spin axis (docs/physics.md §9) that both 3D models apply between
wheel and knuckle: rolling resistance and the ABS-like brake of a `braked` wheel. multibody's UA tyre
(multibody/tyre.py) calls them in its numba force evaluation; exudyn applies them as torque loads updated
before every step (its rolling-disc tyre has neither)."""
import math

from numba import njit

OMEGA_RR = 0.5      # rad/s: the rolling-resistance moment reaches its full value above this spin rate
OMEGA_BRAKE = 1.0   # rad/s: same for the brake torque


@njit(cache=True, inline="always")
def rolling_resistance_moment(f_r, f_z, arm, spin):
    """-f_r F_z h tanh(Omega/OMEGA_RR) [N m] about the spin axis: with h the hub-to-contact distance, a
    resistance force f_r F_z (f_r dimensionless)."""
    return -f_r * f_z * arm * math.tanh(spin / OMEGA_RR)


@njit(cache=True, inline="always")
def brake_moment(eta, mu, f_z, radius, spin_rel):
    """-eta mu F_z R tanh(Omega_rel/OMEGA_BRAKE) [N m] on the wheel against its spin relative to the knuckle
    (the knuckle takes the opposite moment): eta = the share of the locking torque mu F_z R."""
    return -eta * mu * f_z * radius * math.tanh(spin_rel / OMEGA_BRAKE)
