"""Model `exudyn`: the 9-body vehicle of the 3D models (crashlab.models.common.vehicle_3d) built in exudyn
(build.py; one run: run.py, its contact loads step_loads.py, driver inputs driver_loads.py, bookkeeping
and results records.py), with the chassis contact shared with the multibody model (geometry, gap search, force law:
crashlab.models.common.chassis_contact, road_contact, contact_episodes) applied as loads.

exudyn is imported only in run.py and build.py, inside `simulate` (the registry imports this module only when
the model is asked for; `import crashlab.models.exudyn` itself does not import exudyn).
"""
from __future__ import annotations

import time
from typing import Literal

from pydantic import model_validator

from crashlab.model import CollisionModel
from crashlab.models.common.vehicle_3d import build_scene_vehicles
from crashlab.options import ModelOptions, option
from crashlab.outcome import Outcome

from .run import ExudynRun


class ExudynModel(CollisionModel):
    """The multibody model's vehicle (9 rigid bodies, joints, suspension) built with exudyn's items, exudyn's
    rolling-disc penalty tyre, and the multibody model's chassis contact applied as loads.

    Options (the schema `Options` below; why these defaults, the same for every scene):
      step = 1e-3 s              largest step of exudyn's generalized-alpha (implicit, index 3; exudyn's adaptive step
                                 shortens it at contact onsets and when the contact load iteration does not
                                 settle, then doubles it back every 5 steps). The contact loads are iterated to
                                 their values at the step end, so the step sets the accuracy of the contact
                                 force history (170-310 force samples per PC-Crash contact), not its energy.
      min_step = 1e-6 s          shortest step exudyn may take (below it the run fails with a reason)
      onset_tolerance = 1e-3 m   a step in which a contact (car-car, car-barrier, chassis-road) opens deeper than
                                 this is repeated shorter (the multibody model's first-contact control, 1 mm)
      load_tolerance = 1e-3      the contact forces at the step end have settled when a pass changes them by
                                 less than this share of the largest (+ 10 N)
      spectral_radius = 0.8      generalized-alpha numerical damping at infinite frequency (exudyn's default is
                                 0.9): damps the activation transient of the wheel locks and the penalty
                                 tyre's stiff friction zone; the vehicle modes (< 20 Hz) keep > 99.9 % of
                                 their energy per period at 1 ms.
      friction_zone = 0.2 m/s    the rolling disc's dryFrictionProportionalZone (linear regularisation of
                                 Coulomb friction): below this slip speed the friction force is
                                 mu F_z v_slip / zone. 0.2 m/s gives a rolling Clio tyre (F_z 2.4 kN, mu 0.8)
                                 the equivalent cornering stiffness mu F_z V / zone = 133 kN/rad at 50 km/h,
                                 close to the UA tyre's 150 kN/rad, and keeps exudyn's modified Newton at
                                 ~7 iterations per step (0.05 m/s needed ~35 after an impact: 3-4x the cost).
      record_dt = 0.01 s         trajectory sampling
      v_rest = 0.01 m/s, w_rest = 0.01 rad/s, t_sleep = 0.2 s   every chassis slower than this (horizontal
                                 speed, yaw rate) for t_sleep, no contact open: the run stops (the multibody
                                 model's thresholds)
      contact_law = "structure"  the vehicles' CRASH3 crush structures in series, unloading to the scene's
                                 restitution (docs/physics.md §13a); "generic": K delta^n with the scene's
                                 force_law (§13) and the two options below (the multibody model's defaults)
      contact_stiffness = 1.35e6 N/m^1.5   generic law: K of one vehicle against a rigid barrier; car-to-car
                                 pairs use K/2^1.5 for equal K (series Hertz springs)
      contact_exponent = 1.5     generic law: n of F_N = K delta^n (1 + chi delta_dot / delta_dot0)
      v_min = 0.001 m/s          smallest approach velocity delta_dot0 stored at onset (multibody default)

    Tyre: exudyn's `CreateRollingDiscPenalty` (an infinitely thin disc of radius r1 + r2 on the plane z = 0)
    instead of our UA tyre. Normal force K_z delta + C_z delta_dot with K_z and C_z of vehicle_3d (the
    multibody tyre's radial stiffness and damping). In-plane: regularised Coulomb friction, mu F_z along the
    slip velocity of the contact point (dryFriction = [mu, mu] with the scene's road friction, linear below
    `friction_zone`). Differences to the UA tyre: no slip stiffness, no relaxation, no camber or
    self-aligning torque; a rolling wheel's lateral force is mu F_z v_lat / zone, i.e. an equivalent
    cornering stiffness mu F_z V / zone that grows with speed (96 kN/rad per Clio tyre at 10 m/s, 133 kN/rad at
    50 km/h, against UA's constant 150 kN/rad); the full mu F_z is reached at zone, not at the brush model's
    sliding limit. For a locked or sliding wheel both give mu F_z against the sliding velocity. Rolling
    resistance (the vehicle's rolling_resistance f_r, 0 in the PC-Crash scenes) is a moment
    f_r F_z R tanh(omega_rel / 0.5 rad/s) between wheel and knuckle (as our UA tyre), applied as a torque pair
    updated before every step; `braked` (ABS-like) adds the UA tyre's brake moment
    eta mu F_z R tanh(omega_rel / 1 rad/s), eta = 0.95 of the locking torque, the same way.

    Wheels: rolling (revolute joint), locked for the whole run (generic joint, all six axes); a vehicle whose
    wheels lock at some time (an action, locked_after_impact) has the revolute joint plus a spin-lock generic
    joint that is switched on and off between steps; braked (revolute joint + the brake moment above).
    Driver actions and friction zones (docs/physics.md §2a) come from common/driver_inputs, read before every
    step at its middle (`driver_loads.DriverLoads._driver`): wheel state (locked_after_impact through
    effective_mode with the first contact) -> spin locks; brake fraction b -> a brake moment giving the road
    force b sqrt((mu F_z)^2 - F_y^2) (with the wheel's spin inertia I_yy a / R added); steer -> the prismatic
    joints' chassis markers turned to the Ackermann angles of vehicle_3d.steer_angles; zones -> each rolling
    disc's dry friction at its wheel's position predicted half a step on (and the chassis-road contact's at the CG).

    Contact: the numba `common.chassis_contact.contacts` shared with multibody (superellipsoids, horizontal gap search,
    normal_force_chi with the scene's force_law and restitution, the scene's friction law and impact friction) and
    the shared chassis-road contact (common.road_contact: each chassis's lowest point against the
    plane z = 0, Hunt-Crossley, a stiffness that carries the vehicle's weight at 5 mm, road friction and a patch
    moment) give the force and moment on each chassis; they are
    written into a global force and torque load on the chassis. exudyn's generalized-alpha satisfies the
    equations of motion at the step end, so the load must be the contact force of the step-end state: the
    pre-step function sets a predictor (the loads at the step start, extrapolated), the post-Newton function
    (exudyn's PostNewtonUserFunction, its discontinuous iteration, Flores & Ambrosio 2010) evaluates the
    contacts at the converged step end and repeats the step with those loads until they settle (an implicit
    contact force by fixed-point iteration; 1-2 extra passes in a contact step). Held at the step start, as
    before issue 10, the load lagged the penetration by one step and made energy in proportion to the step
    (elastic wall at 50 km/h: restitution 1.05; 200 km/h head-on +7.5 % kinetic energy). Equal and opposite
    loads: linear momentum is exchanged exactly.
    """

    name = "exudyn"
    compiles = "common"  # the shared chassis contact, compiled with numba (models/common)
    driver_inputs = True   # actions and friction zones (docs/physics.md §2a): see driver_loads.DriverLoads._driver
    # the guard's interpenetration check compares rectangular outlines; the contact bodies here are
    # superellipsoids (2/eps = 4) whose rounded corners lie up to ~0.3 m inside the rectangle's: a car at rest
    # 3 cm from a barrier with its corner towards it "overlapped" by 0.26 m (stress scene random 2:17). The
    # model checks the end state with its own contact shapes instead (same tolerance, guard.PENETRATION_TOL).
    guard_skip = frozenset({"interpenetration"})

    class Options(ModelOptions):
        step: float = option(1e-3, "largest step of exudyn's generalized-alpha (shortened at contact onsets and "
                             "unsettled load iterations, then doubled back)", "s", accuracy="smaller", gt=0, le=0.01)
        spectral_radius: float = option(0.8, "generalized-alpha numerical damping at infinite frequency", "",
                                        ge=0, le=1)
        friction_zone: float = option(0.2, "rolling disc's linear friction zone: below this slip speed the tyre "
                                      "force is mu F_z v_slip / zone", "m/s", gt=0)
        record_dt: float = option(0.01, "trajectory sampling", "s", ge=0)
        v_rest: float = option(0.01, "chassis horizontal speed below which a vehicle counts as still", "m/s", gt=0)
        w_rest: float = option(0.01, "chassis yaw rate below which a vehicle counts as still", "rad/s", gt=0)
        t_sleep: float = option(0.2, "every chassis still this long, no contact open: the run stops", "s", ge=0)
        contact_law: Literal["structure", "generic"] = option(
            "structure", "chassis contact force: 'structure' = the vehicles' CRASH3 crush stiffness A + B C per "
            "unit of engaged width, the two structures in series, unloading to the scene's restitution "
            "(docs/physics.md §13a); 'generic' = K delta^n with the scene's force_law (§13)")
        contact_stiffness: float = option(1.35e6, "generic law: K of one vehicle against a rigid barrier; car-to-car "
                                          "pairs use K/2^1.5 for equal K (series Hertz springs)", "N/m^1.5", gt=0)
        contact_exponent: float = option(1.5, "generic law: n of F_N = K delta^n (1 + chi delta_dot / "
                                         "delta_dot0)", "", ge=1)
        v_min: float = option(1e-3, "smallest approach velocity delta_dot0 stored at onset", "m/s", gt=0)
        min_step: float = option(1e-6, "shortest step exudyn may take (below it the run fails with a reason)", "s",
                                 accuracy="smaller", gt=0)
        onset_tolerance: float = option(1e-3, "a step in which a contact (car-car, car-barrier, chassis-road) opens "
                                        "deeper than this is repeated shorter", "m", accuracy="smaller", gt=0)
        load_tolerance: float = option(1e-3, "the contact forces at the step end have settled when a pass changes "
                                       "them by less than this share of the largest (+ 10 N)", "",
                                       accuracy="smaller", gt=0, lt=1)

        @model_validator(mode="after")
        def _min_step_not_above_step(self):
            if self.min_step > self.step:
                raise ValueError("min_step: must be <= step")
            return self

    def simulate(self, scene) -> Outcome:
        t0 = time.perf_counter()
        names = scene.vehicle_names
        vehicles = build_scene_vehicles(scene)  # a vehicle the model cannot build is bad input (exit 2)
        try:
            return ExudynRun(self.options.model_dump(), scene, vehicles).run(t0)
        except Exception as e:  # exudyn raises RuntimeError/ValueError when Newton fails or a state blows up
            return Outcome.failed(names, f"exudyn model: simulation failed: {type(e).__name__}: {e}", self.name,
                                  time.perf_counter() - t0)

