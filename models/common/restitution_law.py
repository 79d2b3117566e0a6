"""The restitution law of the closing speed (crashlab.restitution, docs/physics.md §13b) for compiled kernels:
the core's plain function registered with numba (the core does not import numba), and the kernels' switch
between a constant and the law."""
from numba.extending import register_jitable

from crashlab.restitution import speed_restitution

speed_restitution = register_jitable(speed_restitution)


@register_jitable
def kernel_restitution(e, closing_speed):
    """For numba kernels: e itself, or the law at closing_speed when e is the sentinel E_SPEED_LAW (< 0)."""
    return speed_restitution(closing_speed) if e < 0.0 else e
