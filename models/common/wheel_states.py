"""Wheel states (the scene's `wheels`, crashlab.scene.WHEEL_STATES) as the integer codes the compiled kernels
of every model use: a state's code is its index in WHEEL_STATES."""
from crashlab.scene import WHEEL_STATES

WHEEL_CODES = {state: code for code, state in enumerate(WHEEL_STATES)}
ROLLING, LOCKED, LOCKED_AFTER_IMPACT, BRAKED = (WHEEL_CODES[s] for s in
                                                ("rolling", "locked", "locked_after_impact", "braked"))
