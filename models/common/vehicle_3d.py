"""The 9-body vehicle of the 3D models (thesis chapter 2, Tables 3.2-3.6) built from a VehicleSpec: the
description both multibody (its own joints and UA tyre) and exudyn (exudyn's items) build from, and the
row layouts of its tables (BODY: B_*, suspension SPR: S_*, tyre TYR: T_*, wheel modes).

Bodies: 0 chassis, 1-4 knuckles (FL, FR, RL, RR), 5-8 wheels. Joints: chassis-knuckle TRANSLATIONAL
(the thesis's cylindrical joint with a vertical axis through the wheel centre, plus the steering
constraint that fixes the knuckle's rotation about that axis at the wheel's steer angle), knuckle-wheel
REVOLUTE about the spin axis (REVOLUTE_LOCKED for a locked wheel). Suspension: one spring-damper per
corner from a chassis point to the wheel centre. Tyre: UA (multibody/tyre.py) on each wheel.

Data come from the vehicle file's [multibody] sections; what a file lacks gets the documented defaults
of `DEFAULTS` (scaled from the thesis's Clio where a scale is obvious).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from crashlab.errors import InputError
from crashlab.units import G
from crashlab.vehicle import (
    MB_REFERENCE_RADIUS,
    MB_WHEEL_MASS,
    TORUS_RADIUS_TOL,
    multibody_corner_masses,
    multibody_torus,
    unsprung_problem,
)

NB, NW = 9, 4
CORNERS = ("FL", "FR", "RL", "RR")
# body table BODY[b]: mass [kg], principal inertias [kg m^2]
B_MASS, B_IXX, B_IYY, B_IZZ = 0, 1, 2, 3
# spring-damper row SPR[k] (docs/physics.md §8): bodies i, j, chassis point s'_P (on i), knuckle point s'_Q
# (on j), stiffness, damping, free length, bump-stop length and stiffness, strut axis u'_i (zero: along d)
S_I, S_J, S_P, S_Q, S_K, S_C, S_L0, S_LB, S_KB, S_U = 0, 1, 2, 5, 8, 9, 10, 11, 12, 13
N_S = 16
# tyre row TYR[k] (docs/physics.md §9): wheel and knuckle body, torus radii r1 and r2, radial stiffness and
# damping, slip stiffness, cornering and camber stiffness, rolling resistance, relaxation lengths, tread
# damping (spin, lateral), wheel mode, brake torque / (mu F_z R_e)
(T_WHEEL, T_KNUCKLE, T_R1, T_R2, T_KZ, T_CZ, T_KS, T_KA, T_KG, T_FRR, T_SIG_S, T_SIG_A, T_CS, T_CA,
 T_MODE, T_ETA) = range(16)
N_T = 16
CLIO_R = MB_REFERENCE_RADIUS
DEFAULTS = {
    # wheel + tyre: the Clio's inertias scaled with m R^2 (its 9 kg, the knuckle's 1 kg and the torus: crashlab.vehicle
    # multibody_corner_masses, multibody_torus)
    "wheel_inertia_clio": (3.0580e-2, 3.7103e-1, 3.0580e-2),
    "knuckle_inertia": 0.01,                                # kg m^2 (the thesis gives no geometry)
    "ride_frequency": 1.36, "damping_ratio": 0.48,          # Hz, -: the Clio's 17.239 kN/m, 1939.4 N s/m
    "free_length": 0.25, "joint_z": -0.22,                  # m (Clio)
    "bump_travel": 0.08,                                    # m of compression beyond static before the stop
    "bump_stiffness_factor": 10.0,                          # stop stiffness / spring stiffness
    "radial_stiffness_clio": 200e3, "slip_stiffness_clio": 500e3,   # N/m, N per 980 kg (scaled with mass)
    "camber_to_cornering": 0.2,                             # K_gamma / K_alpha (Clio 30/150)
    "radial_damping_ratio": 0.01,                           # FunctionBay UA sample (docs/physics.md §27)
    "relaxation_over_radius": 1.0,                          # sigma_s = sigma_a = R
    "tread_damping_ratio_spin": 0.5, "tread_damping_ratio_lateral": 0.2,
    "brake_eta": 0.95,                                      # braked (ABS): brake torque / (mu F_z R_e)
}


@dataclasses.dataclass
class Vehicle:
    """Packed parameters of one multibody vehicle (SI) and the geometry needed to place it."""

    name: str
    BODY: np.ndarray        # (9, 4) mass, Ixx, Iyy, Izz
    SPR: np.ndarray         # (4, N_S)
    TYR: np.ndarray         # (4, N_T) (mode set per scene)
    axle_x: np.ndarray      # (4,) wheel-centre x in the chassis frame
    axle_y: np.ndarray      # (4,)
    joint_z: float          # height of the chassis-knuckle joints in the chassis frame
    wheelbase: float
    z_chassis0: float       # first estimate of the chassis CG height
    z_wheel0: np.ndarray    # first estimate of wheel-centre heights
    notes: list
    chassis_shape: np.ndarray = None   # (7,) contact superellipsoid a, b, c, eps1, eps2, x_off, z_off

    @property
    def mass(self):
        return float(self.BODY[:, B_MASS].sum())


def _get(d, key, default, notes, what):
    if key in d:
        return d[key]
    notes.append(f"{what} = {default!r} (default)")
    return default


def build(spec) -> Vehicle:
    sec = spec.sections.get("multibody", {}) or {}
    notes: list[str] = []
    R = spec.wheel_radius
    ch, wh, kn = sec.get("chassis", {}), sec.get("wheel", {}), sec.get("knuckle", {})
    su, ty = sec.get("suspension", {}), sec.get("tyre", {})
    sc = R / CLIO_R
    m_w_default, m_k_default = multibody_corner_masses({}, R)
    m_w = _get(wh, "mass", m_w_default, notes, "wheel.mass")
    I_w = _get(wh, "inertia", [i * (m_w / MB_WHEEL_MASS) * sc ** 2 for i in DEFAULTS["wheel_inertia_clio"]], notes,
               "wheel.inertia")
    m_k = _get(kn, "mass", m_k_default, notes, "knuckle.mass")
    I_k = [DEFAULTS["knuckle_inertia"]] * 3
    for key in ("semi_axes", "shape_exponents"):
        if key in wh:
            notes.append(f"wheel.{key} of [multibody.wheel] not used: the tyre is the torus of [multibody.tyre]")
    # the vehicle's mass and inertias (top level, where a scene override lands) are the parameters' home:
    # the chassis body takes what the wheels and knuckles leave (issue 10: a [multibody.chassis] mass used
    # to win over a mass override)
    m_u4 = 4 * (m_w + m_k)
    m_c = spec.mass - m_u4
    problem = unsprung_problem(sec, R, spec.mass)
    if problem:
        raise ValueError(f"{spec.name}: {problem} (the multibody vehicle)")
    sprung_ratio = 1.0          # the file's [multibody] data scaled to this mass (dynamic similarity)
    if "mass" in ch:
        m_c_file = float(ch["mass"])
        if abs(m_c_file - m_c) > 1e-9 * spec.mass:
            sprung_ratio = m_c / m_c_file
            notes.append(f"mass {spec.mass:g} kg differs from the [multibody] data's {m_c_file + m_u4:g} kg: "
                         f"chassis body {m_c:g} kg, suspension rates x{sprung_ratio:.3f}, tyre radial and "
                         f"slip stiffness x{spec.mass / (m_c_file + m_u4):.3f} (same static deflections)")
    mass_ratio = spec.mass / (m_c / sprung_ratio + m_u4)
    if "inertia" in ch and [float(x) for x in ch["inertia"]] != [spec.roll_inertia, spec.pitch_inertia,
                                                                   spec.yaw_inertia]:
        notes.append("chassis.inertia of [multibody.chassis] ignored: the vehicle's roll/pitch/yaw inertia "
                     "(less the wheels' and knuckles' share) is used")
    BODY = np.zeros((NB, 4))
    BODY[0, 0] = m_c
    BODY[1:5] = [m_k, *I_k]
    BODY[5:9] = [m_w, *I_w]
    a = spec.cg_to_front_axle
    b = spec.wheelbase - a
    t2 = spec.track / 2
    axle_x = np.array([a, a, -b, -b])
    axle_y = np.array([t2, -t2, t2, -t2])
    m_tot = BODY[:, B_MASS].sum()
    # tyre
    r1, r2 = multibody_torus(sec, R)
    for key in ("torus_radius_1", "torus_radius_2"):
        if key not in ty:
            notes.append(f"tyre.{key} = {r1 if key.endswith('1') else r2:g} (default)")
    if abs(r1 + r2 - R) > TORUS_RADIUS_TOL * R:  # a wheel_radius overridden in a scene: the file's torus scaled
        notes.append(f"tyre torus {r1:g} + {r2:g} m scaled to the wheel_radius {R:g} m")
        r1, r2 = r1 * R / (r1 + r2), r2 * R / (r1 + r2)
    kz = _get(ty, "radial_stiffness", DEFAULTS["radial_stiffness_clio"] * m_tot / 980.0 / mass_ratio, notes,
              "tyre.radial_stiffness") * mass_ratio
    ks = _get(ty, "longitudinal_slip_stiffness", DEFAULTS["slip_stiffness_clio"] * m_tot / 980.0 / mass_ratio,
              notes, "tyre.longitudinal_slip_stiffness") * mass_ratio
    ka = ty.get("cornering_stiffness", spec.cornering_stiffness)
    kg = _get(ty, "camber_stiffness", DEFAULTS["camber_to_cornering"] * ka, notes, "tyre.camber_stiffness")
    # the top-level rolling_resistance is the parameter's home (a scene override must reach the tyre); the
    # [multibody.tyre] copy is only reported when it disagrees
    frr = spec.rolling_resistance
    if "rolling_resistance" in ty and float(ty["rolling_resistance"]) != frr:
        notes.append(f"tyre.rolling_resistance {ty['rolling_resistance']} of [multibody.tyre] ignored: "
                     f"the vehicle's rolling_resistance {frr} is used")
    m_u = m_w + m_k
    # radial damping: the thesis's 78 kN s/m (zeta ~ 28 on a 10 kg wheel) is not used, see README
    cz = 2.0 * DEFAULTS["radial_damping_ratio"] * math.sqrt(m_u * kz)
    if "radial_damping" in ty:
        notes.append(f"tyre.radial_damping {ty['radial_damping']} of [multibody.tyre] ignored: the radial damping "
                     f"is {cz:.0f} N s/m, {DEFAULTS['radial_damping_ratio']:g} of critical (models/multibody/"
                     f"README.md, 'Tyre radial damping')")
    sig = DEFAULTS["relaxation_over_radius"] * (r1 + r2)
    m_spin = I_w[1] / (r1 + r2) ** 2
    cs = 2.0 * DEFAULTS["tread_damping_ratio_spin"] * math.sqrt(ks / sig * m_spin)
    ca = 2.0 * DEFAULTS["tread_damping_ratio_lateral"] * math.sqrt(ka / sig * m_tot / 4)
    TYR = np.zeros((NW, N_T))
    for k in range(NW):
        TYR[k, T_WHEEL], TYR[k, T_KNUCKLE] = 5 + k, 1 + k
        TYR[k, [T_R1, T_R2, T_KZ, T_CZ, T_KS, T_KA, T_KG, T_FRR]] = [r1, r2, kz, cz, ks, ka, kg, frr]
        TYR[k, [T_SIG_S, T_SIG_A, T_CS, T_CA, T_ETA]] = [sig, sig, cs, ca, DEFAULTS["brake_eta"]]
    # static estimates: corner loads (from the axle positions), tyre and spring deflections
    load = np.array([b, b, a, a]) / spec.wheelbase / 2 * m_tot * G
    z_w = r1 + r2 - load / kz
    sprung = load - m_u * G
    l0 = _get(su, "free_length", DEFAULTS["free_length"], notes, "suspension.free_length")
    if "stiffness" in su:
        k_s = np.full(4, float(su["stiffness"])) * sprung_ratio
        c_s = np.full(4, float(su.get("damping", 0.0))) * sprung_ratio
    else:
        om = 2 * math.pi * DEFAULTS["ride_frequency"]
        k_s = sprung / G * om ** 2
        c_s = 2 * DEFAULTS["damping_ratio"] * np.sqrt(k_s * sprung / G)
        notes.append("suspension stiffness/damping from ride frequency 1.36 Hz, damping ratio 0.48 (default)")
    l_static = l0 - sprung / k_s
    if "chassis_points" in su:
        pts = np.array(su["chassis_points"], dtype=float)
        # springs vertical: the lower mount is on the knuckle right below the chassis point (see README:
        # Table 3.5's knuckle point [0, 0, 0] would lay the rear spring almost flat at its static length)
        zc = float(np.mean(z_w + l_static - pts[:, 2]))
        notes.append("suspension lower mounts on the knuckles below the chassis points (vertical springs)")
    else:
        zc = spec.cg_height
        pts = np.column_stack([axle_x, axle_y, l_static + z_w - zc])
        notes.append("suspension mounts above the wheel centres, placed so that the chassis CG rests at "
                     "cg_height (default)")
    # chassis inertia: the vehicle's inertias about its CG less the wheels' and knuckles' share (parallel
    # axes, static pose), so that the built vehicle has the vehicle's totals
    zb = np.array([zc] + [z_w[k] for k in range(NW)] * 2)
    xb = np.concatenate([[0.0], axle_x, axle_x])
    yb = np.concatenate([[0.0], axle_y, axle_y])
    mb = BODY[:, B_MASS]
    cg = [float((mb * q).sum() / m_tot) for q in (xb, yb, zb)]
    dx, dy, dz = xb - cg[0], yb - cg[1], zb - cg[2]
    total = (spec.roll_inertia, spec.pitch_inertia, spec.yaw_inertia)
    for ax, (d1, d2, key) in enumerate(((dy, dz, "roll_inertia"), (dx, dz, "pitch_inertia"),
                                        (dx, dy, "yaw_inertia"))):
        share = float((BODY[1:, 1 + ax] + mb[1:] * (d1[1:] ** 2 + d2[1:] ** 2)).sum()
                      + mb[0] * (d1[0] ** 2 + d2[0] ** 2))
        BODY[0, 1 + ax] = total[ax] - share
        if BODY[0, 1 + ax] < 0.3 * total[ax]:
            raise ValueError(f"{spec.name}: {key} = {total[ax]:g} kg m^2 is too small for the multibody "
                             f"vehicle (its wheels and knuckles alone have {share:g} kg m^2 about the CG)")
    SPR = np.zeros((NW, N_S))
    for k in range(NW):
        SPR[k, S_I], SPR[k, S_J] = 0, 1 + k
        SPR[k, S_P:S_P + 3] = pts[k]
        SPR[k, S_Q:S_Q + 3] = [pts[k, 0] - axle_x[k], pts[k, 1] - axle_y[k], 0.0]
        SPR[k, [S_K, S_C, S_L0]] = [k_s[k], c_s[k], l0]
        SPR[k, S_LB] = max(l_static[k] - DEFAULTS["bump_travel"], 0.02)
        SPR[k, S_KB] = DEFAULTS["bump_stiffness_factor"] * k_s[k]
        SPR[k, S_U:S_U + 3] = [0.0, 0.0, -1.0]     # a strut along the translational joint (signed length)
    return Vehicle(spec.name, BODY, SPR, TYR, axle_x, axle_y, DEFAULTS["joint_z"], spec.wheelbase, zc, z_w, notes,
                   chassis_shape(spec, ch, notes, zc))


# m above the road: the highest a default contact body's bottom may lie (docs/physics.md §10, "Chassis bodies"): UN
# Regulation 58 (03 series) §16.1 (a), the largest ground clearance of the rear underrun protection of buses over
# 8 t, trucks and trailers with air suspension; every passenger car of the library lies lower (0.26-0.42 m)
STRUCTURE_BOTTOM_MAX = 0.45


def chassis_shape(spec, ch, notes, zc) -> np.ndarray:
    """Contact superellipsoid of the chassis [a, b, c, eps1, eps2, x_off, z_off] (chassis frame; docs/physics.md
    §10, "Chassis bodies"). [multibody.chassis] semi_axes / shape_exponents (read as 2/eps, the thesis's column)
    when given, centred on the chassis CG; otherwise a = length/2 centred between the bumpers, b = width/2,
    c = 0.25 m scaled with height/1.42 (the Clio's slab), 2/eps = 4. Its height: from its top down to the
    structure's bottom, [multibody.chassis] structure_bottom (m above the road, static; zc the chassis CG height)
    when given, else its own bottom zc - c or STRUCTURE_BOTTOM_MAX, whichever is lower (a bus's or truck's body
    reaches down to its skirt and underrun guard: a car does not pass under it)."""
    if "semi_axes" in ch:
        a, b, c = (float(x) for x in ch["semi_axes"])
        xo = 0.0
    else:
        a, b = spec.length / 2, spec.width / 2
        c = 0.25 * spec.height / 1.42
        xo = (spec.cg_to_front - spec.cg_to_rear) / 2
        notes.append("chassis contact shape from length/width/height, 2/eps = 4 (default)")
    top, bottom = zc + c, zc - c
    if "structure_bottom" in ch:
        zb = float(ch["structure_bottom"])
        if zb >= top:
            raise ValueError(f"{spec.name}: multibody.chassis.structure_bottom = {zb:g} m is not below the top of "
                             f"the chassis contact body ({top:.3f} m above the road)")
    else:
        zb = min(bottom, STRUCTURE_BOTTOM_MAX)
        if zb != bottom:
            notes.append(f"chassis contact body extended down to {zb:g} m above the road (structure_bottom: "
                         f"default at most {STRUCTURE_BOTTOM_MAX:g} m)")
    zo = 0.0
    if zb != bottom:        # only then: a car's body stays bit-identical
        c, zo = (top - zb) / 2, (top + zb) / 2 - zc
    ex = ch.get("shape_exponents", [4.0, 4.0])
    return np.array([a, b, c, 2.0 / float(ex[0]), 2.0 / float(ex[1]), xo, zo])


def steer_angles(veh: Vehicle, steer: float) -> np.ndarray:
    """Per-wheel steer angle: front wheels on an Ackermann linkage with `steer` at the axle centre
    (tan d_k = L / (L / tan steer - y_k)), rear wheels 0."""
    out = np.zeros(NW)
    if steer == 0.0:
        return out
    rr = veh.wheelbase / math.tan(steer)
    for k in (0, 1):
        out[k] = math.atan2(veh.wheelbase, rr - veh.axle_y[k]) if rr > 0 else \
            -math.atan2(veh.wheelbase, -(rr - veh.axle_y[k]))
    return out


def build_scene_vehicles(scene) -> list:
    """The multibody vehicles of a scene. A vehicle this model cannot honour (a mass or inertia too small
    for its wheels and knuckles) is bad input, refused before anything runs: InputError naming the scene
    file and the vehicle entry."""
    vehicles = []
    for i, vs in enumerate(scene.vehicles):
        try:
            vehicles.append(build(vs.spec))
        except ValueError as err:
            raise InputError(scene.source, f"vehicles.{i} ({vs.name})", str(err)) from None
    return vehicles
