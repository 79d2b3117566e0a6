"""The 9-body vehicle of the 3D models (common/vehicle_3d.py) built in exudyn (imported only by this package,
lazily).

All vehicle data come from `crashlab.models.common.vehicle_3d.build(spec)` (one home): body masses and
principal inertias (BODY), wheel-centre positions (axle_x, axle_y), the static estimates of the chassis and
wheel heights (z_chassis0, z_wheel0), the suspension rows (SPR: chassis point, knuckle point, k, c, free
length) and the tyre rows (TYR: r1 + r2 = radius, K_z, C_z). Items per vehicle:

* chassis, 4 knuckles, 4 wheels: `mbs.CreateRigidBody` (Euler-parameter nodes, principal inertia at the CG,
  gravity on every body);
* chassis-knuckle: `CreatePrismaticJoint` along the chassis z axis through the wheel centre (all rotations
  fixed, so a knuckle built at its steer angle keeps it: the multibody model's TRANSLATIONAL joint);
* knuckle-wheel: `CreateRevoluteJoint` about the knuckle's y axis; a `locked` wheel gets a
  `CreateGenericJoint` with all six axes constrained instead; a `locked_after_impact` wheel gets the revolute
  joint plus an inactive generic joint that constrains only the spin rotation (activated at first contact,
  see `lock`);
* suspension: `CreateSpringDamper` from the chassis point to the knuckle point (free length, k, c of SPR);
  the multibody model's bump stop is not built (see README);
* tyre: `CreateRollingDiscPenalty` between ground (the road plane z = 0) and the wheel;
* contact loads: one global `CreateForce` and one global `CreateTorque` at the chassis CG, whose load
  vectors the model sets before every step.
"""
from __future__ import annotations

import math

import numpy as np
from exudyn.utilities import RigidBodyInertia

from crashlab.models.common.rotations import rot_z
from crashlab.models.common.vehicle_3d import NW, S_C, S_K, S_L0, S_P, S_Q, T_CZ, T_KZ, T_R1, T_R2, steer_angles
from crashlab.models.common.wheel_states import LOCKED, LOCKED_AFTER_IMPACT
from crashlab.units import G


def _body(mbs, row, pos, A, vel, omega):
    m, ixx, iyy, izz = row
    # the tensor is set after construction: the thesis's wheel (I_yy > I_xx + I_zz) violates the triangle
    # inequality, which RigidBodyInertia reports on every construction; the data's home is vehicle_3d
    inertia = RigidBodyInertia(mass=float(m), inertiaTensor=np.eye(3))
    inertia.inertiaTensor = np.diag([ixx, iyy, izz])
    return mbs.CreateRigidBody(inertia=inertia,
                               referencePosition=pos, referenceRotationMatrix=A, initialVelocity=vel,
                               initialAngularVelocity=omega, gravity=[0.0, 0.0, -G], returnDict=True)


def build_vehicle(mbs, ground, veh, vs, mu, friction_zone, linear_zone, modes):
    """Create one vehicle of the scene (`veh` from vehicle_3d.build, `vs` the scene's VehicleState) at
    its start pose and speed; `modes`: every wheel-state code its wheels take in the run
    (driver_inputs.action_modes). Returns a dict of item indices (see keys below).

    A vehicle locked for the whole run gets the six-axis generic joint; one that locks at some time
    (an action, locked_after_impact) gets the revolute joint plus a spin lock (active from the start when it
    starts locked), switched by `set_locks`. The prismatic joints' chassis markers are returned (`steer`)
    with their build frames, so that `steer` can turn the knuckles between steps."""
    Rz = rot_z(vs.heading)
    origin = np.array([vs.x, vs.y, 0.0])
    vel0 = vs.speed * np.array([math.cos(vs.heading), math.sin(vs.heading), 0.0])
    om0 = np.array([0.0, 0.0, vs.yaw_rate])
    deltas = steer_angles(veh, vs.steer)
    m = veh.BODY[:, 0]
    # start positions in the vehicle frame (the static estimates of vehicle_3d); the vehicle CG is put on
    # the scene's (x, y)
    local = [np.array([0.0, 0.0, veh.z_chassis0])]
    for k in range(NW):
        local.append(np.array([veh.axle_x[k], veh.axle_y[k], veh.z_wheel0[k]]))
    local += local[1:5]
    cg = sum(mb * p for mb, p in zip(m, local)) / m.sum()
    shift = np.array([cg[0], cg[1], 0.0])
    pos = [origin + Rz @ (p - shift) for p in local]

    def v_at(p):
        r = p - origin
        return vel0 + np.cross(om0, np.array([r[0], r[1], 0.0]))

    chassis = _body(mbs, veh.BODY[0], pos[0], Rz, v_at(pos[0]), om0)
    knuckles, wheels, discs, locks, steer_markers = [], [], [], [], []
    always_locked = modes == {LOCKED}
    lockable = not always_locked and bool(modes & {LOCKED, LOCKED_AFTER_IMPACT})
    for k in range(NW):
        Ak = Rz @ rot_z(deltas[k])
        kn = _body(mbs, veh.BODY[1 + k], pos[1 + k], Ak, v_at(pos[1 + k]), om0)
        vw = v_at(pos[5 + k])
        radius = veh.TYR[k, T_R1] + veh.TYR[k, T_R2]
        rolling = vs.wheels in ("rolling", "locked_after_impact")
        spin = float(vw @ Ak[:, 0]) / radius if rolling else 0.0
        wh = _body(mbs, veh.BODY[5 + k], pos[5 + k], Ak, vw, om0 + spin * Ak[:, 1])
        knuckles.append(kn)
        wheels.append(wh)
        pj = mbs.CreatePrismaticJoint(itemNumbers=[chassis["bodyNumber"], kn["bodyNumber"]], position=pos[1 + k],
                                      axis=Rz[:, 2], useGlobalFrame=True, show=False)
        m0 = mbs.GetObject(pj)["markerNumbers"][0]
        steer_markers.append((m0, np.array(mbs.GetMarkerParameter(m0, "localHT"), dtype=float)))
        if always_locked:
            mbs.CreateGenericJoint(itemNumbers=[kn["bodyNumber"], wh["bodyNumber"]], position=pos[5 + k],
                                   rotationMatrixAxes=Ak, constrainedAxes=[1, 1, 1, 1, 1, 1], useGlobalFrame=True,
                                   show=False)
        else:
            mbs.CreateRevoluteJoint(itemNumbers=[kn["bodyNumber"], wh["bodyNumber"]], position=pos[5 + k],
                                    axis=Ak[:, 1], useGlobalFrame=True, show=False)
        if lockable:
            lk = mbs.CreateGenericJoint(itemNumbers=[kn["bodyNumber"], wh["bodyNumber"]], position=pos[5 + k],
                                        rotationMatrixAxes=Ak, constrainedAxes=[0, 0, 0, 0, 1, 0],
                                        useGlobalFrame=True, show=False)
            mbs.SetObjectParameter(lk, "activeConnector", vs.wheels == "locked")
            locks.append(lk)
        # suspension: chassis point SPR[S_P] (chassis frame) to knuckle point SPR[S_Q] (knuckle frame)
        S = veh.SPR[k]
        mbs.CreateSpringDamper(itemNumbers=[chassis["bodyNumber"], kn["bodyNumber"]],
                               localPosition0=S[S_P:S_P + 3].tolist(), localPosition1=S[S_Q:S_Q + 3].tolist(),
                               referenceLength=float(S[S_L0]), stiffness=float(S[S_K]), damping=float(S[S_C]),
                               show=False)
        T = veh.TYR[k]
        discs.append(mbs.CreateRollingDiscPenalty(
            bodyNumbers=[ground, wh["bodyNumber"]], axisPosition=[0.0, 0.0, 0.0], axisVector=[0.0, 1.0, 0.0],
            discRadius=float(radius), planePosition=[0.0, 0.0, 0.0], planeNormal=[0.0, 0.0, 1.0],
            contactStiffness=float(T[T_KZ]), contactDamping=float(T[T_CZ]), dryFriction=[mu, mu],
            dryFrictionProportionalZone=friction_zone, useLinearProportionalZone=linear_zone, show=False))
    force = mbs.CreateForce(itemNumber=chassis["bodyNumber"], loadVector=[0.0, 0.0, 0.0], bodyFixed=False,
                            show=False)
    torque = mbs.CreateTorque(itemNumber=chassis["bodyNumber"], loadVector=[0.0, 0.0, 0.0], bodyFixed=False,
                              show=False)
    return {"chassis": chassis, "knuckles": knuckles, "wheels": wheels, "discs": discs, "locks": locks,
            "force": force, "torque": torque, "steer": steer_markers, "deltas": np.array(deltas, dtype=float),
            "always_locked": always_locked,
            "nodes": [chassis["nodeNumber"]] + [b["nodeNumber"] for b in knuckles + wheels],
            "mass": m.copy()}


def set_locks(mbs, items, on):
    """Switch the spin locks of a vehicle (a wheel-state change: rolling/braked <-> locked, or
    locked_after_impact at the first contact). Off: the connector is deactivated (the wheel spins up from
    the tyre's friction). On: each lock's wheel-side frame is first set to the current relative orientation
    (A_k R0 = A_w R1 with R the marker frames, so the constraint starts without violation); the wheel's spin
    relative to the knuckle is then removed by the constraint within the next steps."""
    import exudyn as exu
    if not on:
        for lk in items["locks"]:
            mbs.SetObjectParameter(lk, "activeConnector", False)
        return
    for k, lk in enumerate(items["locks"]):
        nk, nw = items["knuckles"][k]["nodeNumber"], items["wheels"][k]["nodeNumber"]
        Ak = np.asarray(mbs.GetNodeOutput(nk, exu.OutputVariableType.RotationMatrix)).reshape(3, 3)
        Aw = np.asarray(mbs.GetNodeOutput(nw, exu.OutputVariableType.RotationMatrix)).reshape(3, 3)
        m0, m1 = mbs.GetObject(lk)["markerNumbers"]
        R0 = np.asarray(mbs.GetMarkerParameter(m0, "localHT"))[:3, :3] @ np.asarray(
            mbs.GetObjectParameter(lk, "rotationMarker0"))
        R1m = np.asarray(mbs.GetObjectParameter(lk, "rotationMarker1"))
        HT1 = np.array(mbs.GetMarkerParameter(m1, "localHT"), dtype=float)
        HT1[:3, :3] = Aw.T @ Ak @ R0 @ R1m.T          # marker frame (localHT) x rotationMarker1 = Aw^T Ak R0
        mbs.SetMarkerParameter(m1, "localHT", HT1)
        mbs.SetObjectParameter(lk, "activeConnector", True)


def steer(mbs, items, deltas):
    """Turn the knuckles to the steer angles `deltas` (per wheel, chassis frame, rad) by turning the chassis
    marker of each prismatic joint about the chassis z axis by the change from the build angle: the joint
    keeps A_c R0 = A_k R1, so A_k = A_c rot_z(delta). Between steps the change is one step's share of a
    ramp (5 deg/s: 0.005 deg per 1 ms step), which the index-3 constraint takes up in the next step."""
    for k, (m0, HT0) in enumerate(items["steer"]):
        d = float(deltas[k] - items["deltas"][k])
        HT = HT0.copy()
        HT[:3, :3] = rot_z(d) @ HT0[:3, :3]
        mbs.SetMarkerParameter(m0, "localHT", HT)
