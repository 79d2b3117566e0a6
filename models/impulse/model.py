"""Model `impulse`: planar impulse-momentum collisions (PC-Crash style) with 3-DOF vehicle motion."""
from __future__ import annotations

import functools
import math
import time

import numpy as np
from pydantic import model_validator

from crashlab.diagnostics import Diagnostics
from crashlab.model import CollisionModel
from crashlab.models.common.driver_inputs import pack_action_tables, pack_zones
from crashlab.models.common.impact_rows import pair_rows, struck_compliance
from crashlab.models.common.planar_vehicle import N_PARAMS, P_MASS, pack_vehicle
from crashlab.options import ModelOptions, option
from crashlab.outcome import PUSH, Outcome
from crashlab.restitution import kernel_value
from crashlab.scene import given_pair

from . import kernel as K
from . import layout as L
from .laws import BRACH, FULL, KUDLICH_SLIBAR, REVERSED, ROUTH, SLIDING, SLIP_REVERSES
from .population import simulate_variants
from .run_warnings import run_warnings

LAWS = {"kudlich-slibar": KUDLICH_SLIBAR, "brach": BRACH, "routh": ROUTH}
KIND_TEXT = {FULL: "full", SLIDING: "sliding", REVERSED: "reversed", L.PUSH: PUSH}
STATUS_TEXT = {L.STATUS_NOT_APPROACHING: "the vehicles do not approach at the given point of impact",
               L.STATUS_NAN: "the state became NaN",
               L.STATUS_STEP_LIMIT: "step limit reached (the time step collapsed)"}


class ImpulseModel(CollisionModel):
    """Planar impulse-momentum model.

    Options (documented defaults, the same for every scene):
      dt = 0.005 s        largest fine step of the Heun integrator; each step is also kept below
                          1 / (fastest decay rate of the regularised tyre forces at the wheels' slip
                          speeds), e.g. 2.4 ms for the Clio on rolling wheels near standstill, 3.6 ms on
                          locked wheels near standstill, dt when they roll or slide at metres per second
                          (planar_vehicle.rate_of_slips)
      coarse_dt = 0.05 s  largest step while every vehicle runs straight, or slides on locked wheels
                          with each wheel's slip velocity turning by at most 0.4 rad within the step,
                          and nothing can touch (docs/physics.md §2)
      onset_tol = 1e-5 m  contact onset located until the outlines overlap by at most this; with
                          1 mm (and the first-touch point) the rest position jittered by 0.7 cm (std of
                          second differences along a start coordinate of a side collision; 1.9 cm
                          before the sustained-contact treatment below) as the impact state wandered
                          within the tolerance, with 0.01 mm by ~0.1 cm, for a few more bisection steps
      record_dt = 0.01 s  trajectory sampling of `simulate` (batch runs record none)
      v_rest = 0.03       m/s and rad/s below which a vehicle out of contact is at rest
      max_impacts = 20    cap on impacts (rows of the impact table) per run and vehicle beyond the first:
                          a run of n vehicles stops and fails (outcome_ok False) after max_impacts x (n - 1)
                          impacts (two cars 20, a 32-car pile-up 620: a chain of n cars has n - 1
                          contacts, each may repeat; a fixed 20 failed the pile-up, issue 27); a contact is
                          never ignored
      crush_time = 0.036 s  the point of impact is the middle of the contact zone that the approach
                          speed v_n at first touch would crush, zone depth = crush_time * v_n
                          (geometry.contact_zone_centroid); 0.036 s = 0.5 m of crush at 50 km/h into a
                          rigid barrier (Campbell's linear crush; the multibody stiffness's calibration);
                          0 = the point where the outlines first touch

    Point of impact and contact plane, unless the scene gives them: at contact onset (overlap of at
    most onset_tol) the contact plane lies along the struck edge (the edge whose normal is the axis of
    least overlap), and the point is the middle of the zone the approach will crush: the centroid of
    the overlap of the outlines pushed crush_time * v_n into each other, moved back to the contact line
    (PC-Crash practice: the POI in the middle of the contact zone, the plane along the struck surface).
    For parallel faces this is the middle of the common face segment, as at first touch; at an angle it
    lies inside the crushed zone rather than on the touching corner. Why not the first-touch point: it
    jumps from the middle of a face to a corner as a heading passes through the parallel, and thesis
    case 3 (V1 at 0 deg into V2's side at 90 deg) sits exactly there: V1's rest heading is 53 deg at
    0 deg and -3 or 105 deg at +-0.05 deg; with the zone 53 +- 1 deg over +-0.5 deg, and a search with
    heading evidence finds the truth (twin 2: 0.000 m at ten seeds against 1.04-1.14 m).
    With [impact] point = "engagement" the point and plane come instead from the outlines moved along their
    velocities until they overlap by the scene's engagement_depth (contact._engagement, docs/physics.md §4).

    Impact laws (docs/physics.md §3): kudlich-slibar and brach (friction against the initial slip, PC-Crash
    style) or routh (friction follows the slip as it stops, sticks or reverses). For the first two every
    impact is also solved on Routh's path (laws.checked_impulse): where its slip reverses, the row says
    slip_reversed and the outcome warns with the error of the law there.

    Sustained contact. An impulse model resolves an impact in an instant, but after it the pair can stay
    in touch: a rolling striker pushes a braked car, a car slides along a wall, a car is squeezed between
    a car and a wall. Applying the impact law again at every re-touch gives ever smaller bounces (e^n v, a
    Zeno sequence), then one micro-impact per step, each a row of "0.3 km/h sliding impacts", until a
    cap, after which contact was ignored and the cars passed through each other (6 of 500 random scenes
    ended overlapping by up to 1.86 m). Choice, per pair, a contact *episode*:
      * it opens with an impact, a touch after the pair was more than SEPARATION = 5 cm apart (or the
        first touch): the impact law with restitution e at the point above, its own row;
      * until the pair is again 5 cm apart, every step whose outlines overlap and approach gets contact
        impulses with the same law and friction but e = 0, at the vertex of the overlap that approaches
        fastest (rigid bodies: the normal velocity is linear over the overlap), repeated until no vertex
        approaches: Moreau's velocity-level non-penetration (Moreau 1988; Stewart & Trinkle 1996),
        normal approach stopped, friction Coulomb-limited (sticking, or sliding at mu_imp). They are
        booked into the episode's row (summed delta-V, yaw-rate change and energy; kind, point and plane
        stay the impact's), those later than crashlab.outcome.PUSH_TIME after the impact into a row of kind "push"
        (one car pushing the other); `contact_intervals` gives each episode's first and last impulse.
    Why 5 cm and plastic: a pair that parts by less than that has not left its crash, its crush zones
    (tens of cm deep at crash speeds: 0.5 m at 50 km/h with crush_time) are still engaged, so a
    re-approach is the same crash pulse, not a new impact with its own rebound; a new impact needs a
    5 cm flight, so impacts cannot chatter. Several contacts at one instant (the squeezed car) are
    solved together by sweeps of sequential impulses over the step's contacts (projected Gauss-Seidel,
    up to 50 sweeps). The impulses act at the end of a step, so a pushing pair gains about a h^2 / 2 of
    overlap per step: a position projection moves the pair apart along the contact normal (positions
    only, split by inverse mass: momentum, energy and the pair's centre of mass unchanged, as
    Box2D's and Chipmunk's split impulse) to keep the overlap below CONTACT_SLOP = 2 mm; a touching
    pair whose overlap passes 4 mm within a step (a far corner swinging in) has that step bisected as at
    an onset. A given collision position's start overlap is left as it is and only prevented from
    deepening; the given impulse keeps its own row. Checked against the analytic push (a free-rolling
    car pushing a locked one: common speed, then deceleration mu g m2 / (m1 + m2)) and a seeded stress
    sweep (tests/test_impulse_sustained_contact.py, tests/test_impulse_stress.py).
    """

    name = "impulse"
    compiles = "impulse"
    contact_depth = False  # rigid outlines, the impact resolved at first touch: no crush depth
    collision_position = True  # a given [impact] point and plane_angle are its impact (docs/physics.md §4)
    driver_inputs = True  # actions and friction zones (docs/physics.md §2a): the kernel's _motion and step policy

    class Options(ModelOptions):
        dt: float = option(0.005, "largest fine step of the Heun integrator (also kept below 1 / the fastest "
                           "tyre-force decay rate)", "s", accuracy="smaller", gt=0, le=0.05)
        coarse_dt: float = option(0.05, "largest step while every vehicle runs straight or slides on locked wheels "
                                  "and nothing can touch",
                                  "s", accuracy="smaller", gt=0, le=1.0)
        onset_tol: float = option(1e-5, "contact onset located until the outlines overlap by at most this", "m",
                                  accuracy="smaller", gt=0, le=0.1)
        record_dt: float = option(0.01, "trajectory sampling of `simulate` (0: none; batch runs record none)", "s",
                                  ge=0)
        v_rest: float = option(0.03, "speed (m/s) and yaw rate (rad/s) below which a vehicle out of contact is at "
                               "rest", "m/s", gt=0, le=1.0)
        max_impacts: int = option(20, "cap on impacts per run and vehicle beyond the first (a run of n vehicles "
                                  "fails after max_impacts x (n - 1) impacts)", "", ge=1, le=10000)
        crush_time: float = option(0.036, "the point of impact is the middle of the zone the approach speed at "
                                   "first touch would crush in this time (0: the first-touch point)", "s",
                                   ge=0, le=1.0)
        broad_phase: bool = option(True, "study switch: False tests every pair's outlines at every step (no "
                                   "bounding-circle rejection; same results, more work)")
        sleeping: bool = option(True, "study switch: False integrates a vehicle at rest at every step (no sleep; "
                                "the run then lasts the scene's duration)")

        @model_validator(mode="after")
        def _coarse_not_finer(self):
            if self.coarse_dt < self.dt:
                raise ValueError("coarse_dt: must be >= dt")
            return self

    def __init__(self, **options):
        super().__init__(**options)
        o = self.options
        self.dt, self.coarse_dt, self.onset_tol = o.dt, o.coarse_dt, o.onset_tol
        self.record_dt, self.v_rest, self.max_impacts, self.crush_time = o.record_dt, o.v_rest, o.max_impacts, \
            o.crush_time

    def impact_cap(self, nv: int) -> int:
        """Impacts a run of nv vehicles may have (the rows its impact array needs): max_impacts x (nv - 1)."""
        return self.max_impacts * max(1, nv - 1)

    # ------------------------------------------------------------------ packing
    def pack(self, scene):
        """Arrays (P, S0, B, cfg, A, NA, zones) of one scene for the kernel (cfg: the run's settings, a
        layout.SETTINGS record; A, NA: the driver's action tables, zones: the friction zones; common/driver_inputs)."""
        P = np.array([pack_vehicle(v.spec, v.wheels, v.steer) for v in scene.vehicles]).reshape(-1, N_PARAMS)
        S0 = np.array([[v.x, v.y, v.heading, v.speed * math.cos(v.heading), v.speed * math.sin(v.heading),
                        v.yaw_rate] for v in scene.vehicles])
        B = np.array([[b.x, b.y, b.heading, b.length / 2, b.width / 2] for b in scene.barriers]).reshape(-1, 5)
        cfg = np.zeros(1, L.SETTINGS)[0]  # the run's settings (layout.SETTINGS): no given impact unless set
        imp = scene.impact
        cfg["road_friction"], cfg["restitution"], cfg["impact_friction"] = scene.road.friction, kernel_value(imp), \
            imp.friction
        cfg["law"], cfg["duration"], cfg["stop_at_rest"] = LAWS[imp.law], scene.duration, scene.stop_at_rest
        if imp.point is not None:
            cfg["given"], cfg["given_x"], cfg["given_y"] = True, imp.point[0], imp.point[1]
            cfg["given_plane"] = imp.plane_angle
            cfg["given_i"], cfg["given_j"] = given_pair(scene)
        cfg["dt"], cfg["coarse_dt"], cfg["record_dt"] = self.dt, self.coarse_dt, self.record_dt
        cfg["onset_tol"], cfg["v_rest"] = self.onset_tol, self.v_rest
        cfg["max_impacts"] = self.impact_cap(len(scene.vehicles))
        cfg["crush_time"] = self.crush_time
        cfg["engagement"], cfg["engagement_depth"] = imp.engagement, imp.engagement_depth
        cfg["broad_phase"], cfg["sleeping"] = self.options.broad_phase, self.options.sleeping
        A, NA = pack_action_tables(scene.vehicles)
        return P, S0, B, cfg, A, NA, pack_zones(scene.road)

    # ------------------------------------------------------------------ running
    def simulate(self, scene) -> Outcome:
        t0 = time.perf_counter()
        P, S0, B, cfg, A, NA, zones = self.pack(scene)
        nv = P.shape[0]
        rest, final, contact = np.empty((nv, 3)), np.empty((nv, 3)), np.empty((nv, 4))
        imp, diag = np.zeros((self.impact_cap(nv), L.N_IMP)), np.zeros(L.N_DIAG)
        n_rec = int(scene.duration / self.record_dt) + 3 if self.record_dt > 0 else 0
        traj = np.zeros((n_rec, nv, 7))
        K.simulate_one(P, S0, B, cfg, A, NA, zones, rest, final, contact, imp, traj, diag)
        out = self._outcome(scene, P, rest, final, contact, imp, diag, time.perf_counter() - t0)
        nr = int(diag[L.D_NREC])
        out._trajectories = {v.name: {"t": traj[:nr, i, 0], "x": traj[:nr, i, 1], "y": traj[:nr, i, 2],
                                      "heading": traj[:nr, i, 3], "vx": traj[:nr, i, 4],
                                      "vy": traj[:nr, i, 5], "yaw_rate": traj[:nr, i, 6]}
                             for i, v in enumerate(scene.vehicles)}
        return out

    def simulate_batch(self, scenes) -> list[Outcome]:
        """All scenes in one parallel compiled call (scenes of the same composition)."""
        if not scenes:
            return []
        t0 = time.perf_counter()
        packs = [self.pack(s) for s in scenes]
        shapes = {(p[0].shape, p[2].shape, p[4].shape, p[6][0].shape, p[6][2].shape) for p in packs}
        if len(shapes) > 1:
            return [self.simulate(s) for s in scenes]
        P, S0, B, cfg, A, NA = (np.stack([p[k] for p in packs]) for k in range(6))
        ZC, ZS, ZMU, ZBOX = (np.stack([p[6][k] for p in packs]) for k in range(4))
        n, nv = P.shape[0], P.shape[1]
        rest, final, contact = np.empty((n, nv, 3)), np.empty((n, nv, 3)), np.empty((n, nv, 4))
        imp, diag = np.zeros((n, self.impact_cap(nv), L.N_IMP)), np.zeros((n, L.N_DIAG))
        K.simulate_many(P, S0, B, cfg, A, NA, ZC, ZS, ZMU, ZBOX, rest, final, contact, imp, diag)
        wall = (time.perf_counter() - t0) / n
        return [self._outcome(s, P[k], rest[k], final[k], contact[k], imp[k], diag[k], wall)
                for k, s in enumerate(scenes)]

    # ------------------------------------------------------------------ results
    def simulate_population(self, scene, fields, values):
        """The base scene packed once, each variant's values written into the kernel's arrays, one parallel
        call, the results as arrays (population.py; crashlab.model for the contract)."""
        return simulate_variants(self, scene, fields, values)

    def status_text(self) -> dict:
        """Why a run with each failed kernel status failed."""
        return {**STATUS_TEXT, L.STATUS_IMPACT_CAP: f"more impacts than max_impacts = {self.max_impacts} x (vehicles "
                "- 1): the run was stopped there"}

    def _outcome(self, scene, P, rest, final, contact, imp, diag, wall) -> Outcome:
        names = scene.vehicle_names
        status = int(diag[L.D_STATUS])
        warnings = [self.status_text()[status]] if status != L.STATUS_OK else []
        ok = status == L.STATUS_OK
        n_imp = int(diag[L.D_IMPACTS])
        imp = imp[:n_imp].copy()
        rows = functools.partial(_impact_rows, names, P[:, P_MASS].copy(), imp,
                                 tuple(v.spec for v in scene.vehicles))
        intervals = _episode_intervals(imp)
        d = diag.tolist()
        # core (crashlab.diagnostics): the onset and deepening bisections are the rejected steps; built
        # directly, not from a dict (a batch builds thousands)
        diagnostics = Diagnostics(
            steps=int(d[L.D_STEPS]), rejected_steps=int(d[L.D_BISECT]), t_end=d[L.D_T_END],
            episodes=int((imp[:, L.I_KIND] != L.PUSH).sum()),  # (a push row continues its impact's episode, §5)
            max_penetration=d[L.D_MAX_DEPTH],
            extra={"coarse_steps": int(d[L.D_COARSE]), "kinetic_energy_start": d[L.D_KE0],
                   "energy_dissipated_impacts": d[L.D_E_IMPACT], "contact_impulses": int(d[L.D_FOLLOW]),
                   "projected": d[L.D_PROJECTED],
                   # the work: awake vehicles integrated (summed over steps), outline tests of pairs the
                   # bounding circles did not reject (sleeping vehicles and distant pairs skipped)
                   "vehicle_steps": int(d[L.D_VEHICLE_STEPS]), "outline_tests": int(d[L.D_NARROW])})
        warnings += run_warnings(scene, names, P[:, P_MASS], imp)
        return Outcome(names, rest.copy(), final.copy(), contact.copy(), d[L.D_CONTACT_T], None, rows,
                       diagnostics, warnings, ok, self.name, wall, contact_intervals=intervals,
                       impact_energy=imp[:, L.I_ENERGY].copy())

def _episode_intervals(imp) -> list[tuple[float, float]]:
    """(first, last impulse) [s] of each contact episode: an impact's row, through its push row if it has one (§5)."""
    out, last = [], {}
    for r in imp.tolist():
        pair = (r[L.I_I], r[L.I_J])
        if r[L.I_KIND] == L.PUSH and pair in last:
            k = last[pair]
            out[k] = (out[k][0], r[L.I_T_END])
        else:
            last[pair] = len(out)
            out.append((r[L.I_T], r[L.I_T_END]))
    return out


def _impact_rows(names, mass, imp, specs):
    """Impact table rows (SI), one per vehicle per impact; an impact's row holds the sums over its contact
    episode (the impact and its follow-up contact impulses, `contact_impulses` of them, the last at
    `t_end`), up to crashlab.outcome.PUSH_TIME after the impact, the rest of a longer episode in a row of kind "push"
    (§5); kind, point and plane are the impact's; the energy shared by the struck sides' structures (the
    vehicles' specs, impact_rows.struck_compliance)."""
    compliance = struck_compliance(specs)
    rows = []
    for r in imp:
        pn, pt, plane = r[L.I_PN], r[L.I_PT], r[L.I_PLANE]
        nx, ny = math.sin(plane), -math.cos(plane)
        ix, iy = pn * nx - pt * ny, pn * ny + pt * nx  # impulse on j; -impulse on i
        dv = ((r[L.I_DVX_I], r[L.I_DVY_I], r[L.I_DR_I]), (r[L.I_DVX_J], r[L.I_DVY_J], r[L.I_DR_J]))
        rows += pair_rows(names, mass, int(r[L.I_I]), int(r[L.I_J]), r[L.I_T], r[L.I_ENERGY], dv,
                          ((-ix, -iy), (ix, iy)), (r[L.I_HEAD_I], r[L.I_HEAD_J]), (r[L.I_PX], r[L.I_PY]), plane,
                          KIND_TEXT[int(r[L.I_KIND])], (r[L.I_SIDE_I], r[L.I_SIDE_J]), compliance, t_end=r[L.I_T_END],
                          contact_impulses=int(r[L.I_N_FOLLOW]), slip_reversed=bool(r[L.I_REVERSED] == SLIP_REVERSES))
    return rows
