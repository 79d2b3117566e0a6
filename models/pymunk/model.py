"""Model `pymunk`: a general-purpose 2D rigid-body engine (Chipmunk2D through pymunk) with impulse
contacts, driven by the same planar tyre/ground forces as the impulse model.

pymunk is imported inside `simulate` only, so listing the models never imports it.
"""
from __future__ import annotations

import math
import time

from crashlab.model import CollisionModel
from crashlab.options import ModelOptions, option
from crashlab.outcome import Outcome

from .run import Run


class PymunkModel(CollisionModel):
    """Vehicles and barriers as Chipmunk polygons, SI units, impulse contacts (sequential impulses).

    Options (documented defaults, the same for every scene):
      dt = 0.00025 s         fixed step of the engine. Two things set it. (1) Chipmunk's friction impulses
                             act on the two surface points of a penetrating contact, a penetration
                             (about v dt) apart, so angular momentum is not conserved exactly; on an
                             oblique car-to-car impact with the road off the error about the system's
                             centre of mass is 4.1 / 1.8 / 0.64 / 0.17 / 0.08 % at dt = 2 / 1 / 0.5 /
                             0.25 / 0.1 ms (studies/pymunk/angular_momentum_vs_step.py; with the
                             impact friction set to 0 it is 10-15 times smaller); 0.25 ms is the
                             largest step of that series under 0.5 %, with a factor 3 of margin.
                             (2) The tyre forces are evaluated once per step (semi-implicit Euler): at
                             0.25 ms the rest poses of the side collision are within 1 cm and 0.1 deg of
                             those at 0.1 ms.
      iterations = 100       solver iterations per step. A crash is a handful of contact points, so
                             the cost is not measurable; the sequential impulses on a two-point
                             manifold (face-to-face contact) converge to the simultaneous solution by
                             about 30 sweeps (Chipmunk's default 10 leaves 0.1 deg/s differences in the
                             yaw-rate change of the side collision); 100 leaves margin.
      collision_slop = 1e-4 m  penetration allowed without positional correction. Chipmunk's default
                             (0.1) is meant for pixels; in metres it would let the cars sink 10 cm into
                             each other. 0.1 mm is far below any crush depth yet above round-off.
                             An accuracy knob ("smaller"): a tolerance on the overlap, whose limit 0 is
                             the rigid non-penetration the model stands for.
      collision_bias = 0.0018  fraction of a penetration left after one second (Chipmunk's default,
                             (1 - 0.1)^60). The correction is a split impulse: it moves positions only
                             and never changes the velocities, so it adds no momentum or energy.
                             Not an accuracy knob: a stabilisation rate (as multibody's baumgarte), and
                             neither direction converges to the model (0 removes the whole penetration
                             in one step, 1 never removes it).
      record_dt = 0.01 s     trajectory sampling (0: none)
      v_rest = 0.03          m/s and rad/s below which a vehicle out of contact is at rest (as impulse)
      ground_forces = True   tyre/road forces on; False leaves only the contacts (momentum checks)

    The pair's restitution and friction are set exactly from the scene's [impact] on the arbiter in
    every pre-solve (Chipmunk would otherwise multiply the per-shape coefficients). The engine finds its own
    contacts: a scene with a collision position runs from its approach (crashlab.model, a warning says so).

    Impacts: one contact episode of a pair is one impact: from Chipmunk's begin until the pair is 5 cm apart (a
    re-touch before continues it), its contact later than 0.3 s after the touch a row of kind "push" (the rule
    of every model, crashlab.outcome; docs/physics.md §15, §18). Its delta-V and yaw-rate
    change are the velocity jumps the contact caused, i.e. the change of velocity over the steps of the
    episode minus the part of the tyre forces (known exactly: Chipmunk adds F dt / m); the energy is the
    kinetic energy the contact impulses removed. The point is the middle of the contact points and the
    plane the tangent of the contact normal at the episode's first step; `contact_intervals` (and the rows'
    `duration`) span the episode's steps with contact impulses.

    What differs from the impulse model by construction: when two flat faces meet (a bumper on a
    door), Chipmunk's contact has two points, one at each end of the contact segment, and both get the
    restitution target. The normal relative velocity is then uniform along the segment after the impact,
    i.e. the relative rotation is stopped: the two cars leave a face-to-face impact with the same yaw
    rate, where a single-point impulse (PC-Crash, model `impulse`) lets them spin apart. This is the
    main source of the different rest poses in the side collision.
    """

    name = "pymunk"
    compiles = "pymunk"  # its numba ground contact (models/pymunk/ground.py)
    driver_inputs = True  # actions and friction zones (docs/physics.md §2a) through ground.ground_forces

    class Options(ModelOptions):
        dt: float = option(0.00025, "fixed step of the engine (Chipmunk's contact friction breaks angular "
                           "momentum by about the step's penetration; the tyre forces are evaluated once a step)",
                           "s", accuracy="smaller", gt=0, le=0.01)
        iterations: int = option(100, "sequential-impulse solver iterations per step", "", accuracy="larger",
                                 ge=1, le=10000)
        collision_slop: float = option(1e-4, "penetration allowed without positional correction", "m",
                                       accuracy="smaller", ge=0, le=0.1)
        collision_bias: float = option(0.0017970074436457143, "fraction of a penetration left uncorrected after "
                                       "one second (split impulse: positions only)", "", ge=0, le=1.0)
        record_dt: float = option(0.01, "trajectory sampling (0: none)", "s", ge=0)
        v_rest: float = option(0.03, "speed (m/s) and yaw rate (rad/s) below which a vehicle out of contact is at "
                               "rest", "m/s", gt=0, lt=10.0)
        ground_forces: bool = option(True, "test switch: False removes the tyre/road forces (momentum checks)")
        sleeping: bool = option(True, "study switch: False never puts a vehicle at rest to sleep (tyre forces "
                                "evaluated at every step; the run then lasts the scene's duration)")

    def __init__(self, **options):
        super().__init__(**options)
        o = self.options
        self.dt, self.iterations, self.record_dt, self.v_rest = o.dt, o.iterations, o.record_dt, o.v_rest
        self.collision_slop, self.collision_bias, self.ground_forces = o.collision_slop, o.collision_bias, \
            o.ground_forces
        self.sleeping = o.sleeping

    # ------------------------------------------------------------------ running
    def simulate(self, scene) -> Outcome:
        t0 = time.perf_counter()
        for v in scene.vehicles:  # Chipmunk aborts the process on others (a population's unchecked rows)
            if not (0.0 < v.spec.mass < math.inf and 0.0 < v.spec.yaw_inertia < math.inf):
                return Outcome.failed(scene.vehicle_names, f"{v.name}: mass {v.spec.mass:g} kg and yaw inertia "
                                      f"{v.spec.yaw_inertia:g} kg m^2 must be positive and finite", self.name,
                                      time.perf_counter() - t0)
        try:
            return Run(self, scene).run(t0)
        except ImportError as err:
            return Outcome.failed(scene.vehicle_names, f"pymunk is not installed ({err})", self.name,
                                  time.perf_counter() - t0)
