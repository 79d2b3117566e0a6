"""The impulse kernel's array layouts (models/impulse/kernel.py): the run's settings (SETTINGS), the impact record
(I_*, one row per impact), the diagnostics (D_*), a vehicle's driver inputs at a step's start (IN_*), the run's
status codes and how an engagement point was placed (ENGAGE_*). model.py packs and reads them."""
import numpy as np

# the run's settings: one record per scene (a numpy structured scalar, a numba Record in the kernel), packed once by
# model.pack, changed per variant by population.pack_variants; booleans are booleans, counts and indices integers
SETTINGS = np.dtype([
    ("road_friction", np.float64),  # mu of the road outside friction zones
    ("restitution", np.float64),  # e of an impact (crashlab.restitution.kernel_value: or E_SPEED_LAW)
    ("impact_friction", np.float64),  # the contact friction of impacts and contact impulses (§3)
    ("law", np.int64),  # the impulse law (laws.py, model.LAWS)
    ("duration", np.float64),
    ("stop_at_rest", np.bool_),  # end the run once every vehicle sleeps
    ("given", np.bool_),  # an impact at t = 0 at a given point and contact plane (PC-Crash style)
    ("given_x", np.float64), ("given_y", np.float64), ("given_plane", np.float64),  # its point, plane angle
    ("given_i", np.int64), ("given_j", np.int64),  # its pair (vehicle, vehicle or barrier index)
    ("dt", np.float64), ("coarse_dt", np.float64), ("record_dt", np.float64),  # step sizes (kernel docstring)
    ("onset_tol", np.float64),  # overlap at which contact onset's bisection stops
    ("v_rest", np.float64),  # speed and yaw rate below which a vehicle is at rest
    ("max_impacts", np.int64),  # the impact record's rows a run may fill
    ("crush_time", np.float64),  # the point of impact: the zone crushed in this time (§4)
    ("broad_phase", np.bool_), ("sleeping", np.bool_),  # study switches (comparison scaling)
    ("engagement", np.bool_), ("engagement_depth", np.float64),  # [impact] point = "engagement" (§4)
], align=True)
# impact record: one row per impact (contact episode); the episode's follow-up contact impulses are
# summed into it (dv, energy, impulse in the impact's n-t frame); I_T_END is its last impulse
# I_REVERSED: what Routh's path says of the impact (laws.checked_impulse: 0, SLIP_REVERSES, SLIP_OVERSHOOT); the
# impact's own impulse (I_OWN_*: n-t frame, yaw-rate changes of i and j) and Routh's for it (I_ALT_*), for the
# warning of a law that does not follow the slip (run_warnings._slip_warnings)
(I_T, I_I, I_J, I_DVX_I, I_DVY_I, I_DR_I, I_DVX_J, I_DVY_J, I_DR_J, I_ENERGY, I_PN, I_PT, I_KIND, I_PX,
 I_PY, I_PLANE, I_HEAD_I, I_HEAD_J, I_T_END, I_N_FOLLOW, I_REVERSED, I_OWN_PN, I_OWN_PT, I_OWN_DR_I, I_OWN_DR_J,
 I_ALT_PN, I_ALT_PT, I_ALT_DR_I, I_ALT_DR_J, I_CLOSING, I_ENGAGE, I_ENGAGE_RATIO, I_SIDE_I, I_SIDE_J, I_WIDTH,
 I_CAPACITY, I_REIMPACT) = range(37)
N_IMP = 37  # I_CLOSING: the normal closing speed at the impact, m/s (restitution = "speed", §13b)
# I_WIDTH, I_CAPACITY: the impact's engaged width [m] and the energy [J] it absorbs within the struck crush zones
# (planar_vehicle.engaged_capacity; run_warnings: an impact that dissipates more, §4 "Engaged width")
# I_SIDE_I, I_SIDE_J: the face of i and of j the impact strikes (planar_vehicle.struck_side: 0 front, 1 rear, 2 left,
# 3 right; 0 for a barrier), whose structures share the energy (§21)
# I_ENGAGE: how [impact] point = "engagement" placed the impact (ENGAGE_*; 0 for every other placement and for
# follow-up impulses); I_ENGAGE_RATIO: the crushed faces' smaller principal value over the larger (_engagement)
ENGAGE_USED, ENGAGE_AMBIGUOUS, ENGAGE_FALLBACK = 1, 2, 3
# I_KIND: the impact's (laws.FULL, SLIDING, REVERSED), or PUSH: the episode's contact impulses later than PUSH_TIME
# (crashlab.outcome) after its impact, one car pushing the other, in a row of their own (docs/physics.md §5); its
# I_CLOSING is NaN (no impact). I_REIMPACT: 1 for a re-impact's row, a contact impulse closing at
# crashlab.outcome.REIMPACT_SPEED or faster in a push or later than PUSH_TIME after its impact (plastic, as every
# follow-up; its I_CLOSING NaN), which impacts._settle_reimpacts makes a push's where its impulse is small
PUSH = 3
AMBIGUOUS_RATIO = 0.9  # principal values within 10 % of each other: the faces give no plane (docs/physics.md §4)
# diagnostics
(D_STEPS, D_IMPACTS, D_NREC, D_T_END, D_STATUS, D_CONTACT_T, D_BISECT, D_COARSE, D_MAX_DEPTH, D_KE0,
 D_E_IMPACT, D_FOLLOW, D_PROJECTED, D_VEHICLE_STEPS, D_NARROW) = range(15)
N_DIAG = 15  # D_VEHICLE_STEPS: awake vehicles integrated, summed over steps; D_NARROW: outline tests
# a vehicle's driver inputs at the step's start (_heun): wheel state, brake, steer and the cosines and sines of
# its steer and heading
IN_MODE, IN_BRAKE, IN_STEER, IN_COS_STEER, IN_SIN_STEER, IN_COS_HEADING, IN_SIN_HEADING = range(7)
N_IN = 7
STATUS_OK, STATUS_NOT_APPROACHING, STATUS_IMPACT_CAP, STATUS_NAN, STATUS_STEP_LIMIT = 0, 1, 2, 3, 4
