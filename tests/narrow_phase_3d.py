"""Test tool: the general 3D narrow phase between two convex superellipsoids (docs/physics.md §12): signed
gap, normal, contact points. The models use the horizontal gap search of models/common/narrow_phase.py
(vehicles crush horizontally); this 3D tool is kept with the tests that check it and the geometry.

`signed_gap(sh1, r1, A1, sh2, r2, A2, warm=None, info=None)` ->
    (gap, normal, P1, P2, converged)
    gap < 0: penetration depth -gap (minimum translational distance), gap > 0: minimum distance;
    normal: unit outward normal of body 1 at P1 (points from body 1 towards body 2);
    P1 on surface 1, P2 on surface 2 (global); converged: the result passed the acceptance checks.
    warm: previous info["warm"] (local coordinates [xi_P on 1; xi_Q on 2], 6 floats) — tried first.
    info (dict, optional) receives method ('newton-warm' | 'newton' | 'slsqp'), iterations, warm.

Pipeline:
1. Seed (§10): the signed gap of convex bodies is max over unit d of -(h1(d) + h2(-d)) (h the global
   support functions); it is evaluated with the closed-form support function on 200 Fibonacci
   directions, the best one refined by 8 levels of a 5 x 5 tangent-plane grid (~400 support calls,
   a few microseconds), and that direction's support points sigma1(d), sigma2(-d) seed Newton. (No
   GJK/EPA: this is simpler, branch-free, and lands in the right basin.)
2. Common-normal Newton-Raphson (Lopes et al. 2010, §12): 6 unknowns (local points), residuals
   n_P.t_Q, n_P.b_Q, d.t_Q, d.b_Q, G1(P), G2(Q) (the well-scaled G in place of F: same zero set),
   Householder tangent basis h = n + sgn(n_x)|n| e_x (sgn(0) = +1; the sign is frozen within one Jacobian
   evaluation so the frame is smooth), Jacobian by central differences, step limited to a quarter of the
   smallest semi-axis, both points re-projected radially onto their surfaces after each step.
3. Acceptance (§12): anti-parallel normals n_P.n_Q <= -0.99 and the gap vector along the normal
   (d^.n_P >= 0.99 separated, <= -0.99 penetrating; skipped when |d| < 1e-9), and the gap not below the
   seed's value. Any accepted pair satisfies P = sigma1(n_P), Q = sigma2(-n_P), so its gap equals
   g(n_P) <= max g = the true signed gap: a pair is wrong only if it is a lower stationary point of g
   (e.g. the back-side pair of §12), and the seed value (<= max g) rejects those.
   NOT used: the Lopes/fcl test "penetrating iff Q inside body 1" — for a deep penetration the
   minimum-translation pair can have Q outside body 1 (seen on random pairs); the sign comes from
   s = n_P.(Q - P) as in Portal's code.
4. Fallback: scipy.optimize.minimize SLSQP on Portal's formulation (§12, constraint set 'normals_dot'
   by default or 'normals_cross'): min |P2-P1|^2 s.t. G1(P1) = 0, G2(P2) = 0, n1.n2 + 1 = 0, points in
   cubes of half-size 1.1 max(a,b,c) around their centres; sign from s = n1.(P2-P1). Its result is then
   polished by Newton; whatever passes the checks is returned, else the SLSQP point with converged False.
"""
import math

import numpy as np
from geometry_3d import G_global, G_local, grad_G_local, normal_global, normal_local, radial_project
from numba import njit
from scipy.optimize import minimize

from crashlab.models.common.superellipsoid import mat_t_vec, mat_vec, support_local, support_value_local


def _fibonacci(n):
    i = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * i / n)
    th = np.pi * (1 + 5 ** 0.5) * i
    return np.stack([np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), np.cos(phi)], axis=1)


SEED_DIRS = _fibonacci(200)


# ----------------------------------------------------------------------------------------------------
# numba kernels
# ----------------------------------------------------------------------------------------------------
@njit(cache=True)
def householder_tb(n0, n1, n2, sgn):
    """Tangent t = H[:,1], binormal b = H[:,2] of H = I - 2hh^T/h^Th, h = n + sgn |n| e_x (§12)."""
    nn = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    h0 = n0 + sgn * nn
    hh = h0 * h0 + n1 * n1 + n2 * n2
    k = 2.0 / hh
    t = (-k * h0 * n1, 1.0 - k * n1 * n1, -k * n2 * n1)
    b = (-k * h0 * n2, -k * n1 * n2, 1.0 - k * n2 * n2)
    return t, b


@njit(cache=True)
def _residual(q, sh1, r1, A1, sh2, r2, A2, sgn, out):
    nPl = normal_local(q[0], q[1], q[2], sh1)
    nQl = normal_local(q[3], q[4], q[5], sh2)
    nP = mat_vec(A1, nPl[0], nPl[1], nPl[2])
    nQ = mat_vec(A2, nQl[0], nQl[1], nQl[2])
    P = mat_vec(A1, q[0], q[1], q[2])
    Q = mat_vec(A2, q[3], q[4], q[5])
    d0 = r2[0] + Q[0] - r1[0] - P[0]
    d1 = r2[1] + Q[1] - r1[1] - P[1]
    d2 = r2[2] + Q[2] - r1[2] - P[2]
    if sgn == 0.0:
        sgn = 1.0 if nQ[0] >= 0.0 else -1.0
    t, b = householder_tb(nQ[0], nQ[1], nQ[2], sgn)
    out[0] = nP[0] * t[0] + nP[1] * t[1] + nP[2] * t[2]
    out[1] = nP[0] * b[0] + nP[1] * b[1] + nP[2] * b[2]
    out[2] = d0 * t[0] + d1 * t[1] + d2 * t[2]
    out[3] = d0 * b[0] + d1 * b[1] + d2 * b[2]
    out[4] = G_local(q[0], q[1], q[2], sh1)
    out[5] = G_local(q[3], q[4], q[5], sh2)
    return sgn


@njit(cache=True)
def _solve6(J, rhs, x):
    """Gaussian elimination with partial pivoting; returns False if (numerically) singular."""
    M = J.copy()
    v = rhs.copy()
    n = 6
    scale = 0.0
    for i in range(n):
        for j in range(n):
            scale = max(scale, abs(M[i, j]))
    if scale == 0.0:
        return False
    for k in range(n):
        p = k
        for i in range(k + 1, n):
            if abs(M[i, k]) > abs(M[p, k]):
                p = i
        if abs(M[p, k]) < 1e-14 * scale:
            return False
        if p != k:
            for j in range(n):
                M[k, j], M[p, j] = M[p, j], M[k, j]
            v[k], v[p] = v[p], v[k]
        for i in range(k + 1, n):
            f = M[i, k] / M[k, k]
            for j in range(k, n):
                M[i, j] -= f * M[k, j]
            v[i] -= f * v[k]
    for i in range(n - 1, -1, -1):
        s = v[i]
        for j in range(i + 1, n):
            s -= M[i, j] * x[j]
        x[i] = s / M[i, i]
    return True


@njit(cache=True)
def newton_common_normal(q0, sh1, r1, A1, sh2, r2, A2, maxit=150, tol=1e-10):
    """Common-normal Newton (§12) from local points q0 = [xi_P; xi_Q]. Returns (q, converged, iters).
    converged: step < tol * L (L = largest semi-axis) or residual norm < 1e-13, within maxit."""
    q = q0.copy()
    p = radial_project(q[0], q[1], q[2], sh1)
    q[0], q[1], q[2] = p[0], p[1], p[2]
    p = radial_project(q[3], q[4], q[5], sh2)
    q[3], q[4], q[5] = p[0], p[1], p[2]
    L = max(max(sh1[0], sh1[1]), max(sh1[2], max(sh2[0], max(sh2[1], sh2[2]))))
    lmin = min(min(sh1[0], sh1[1]), min(sh1[2], min(sh2[0], min(sh2[1], sh2[2]))))
    phi = np.empty(6)
    fp = np.empty(6)
    fm = np.empty(6)
    J = np.empty((6, 6))
    dq = np.empty(6)
    qp = np.empty(6)
    hstep = 1e-7 * L
    for it in range(maxit):
        sgn = _residual(q, sh1, r1, A1, sh2, r2, A2, 0.0, phi)
        rn = 0.0
        for i in range(6):
            rn += phi[i] * phi[i]
        if math.sqrt(rn) < 1e-13:
            return q, True, it
        for j in range(6):
            for i in range(6):
                qp[i] = q[i]
            qp[j] = q[j] + hstep
            _residual(qp, sh1, r1, A1, sh2, r2, A2, sgn, fp)
            qp[j] = q[j] - hstep
            _residual(qp, sh1, r1, A1, sh2, r2, A2, sgn, fm)
            for i in range(6):
                J[i, j] = (fp[i] - fm[i]) / (2.0 * hstep)
        for i in range(6):
            phi[i] = -phi[i]
        if not _solve6(J, phi, dq):
            return q, False, it
        nrm = 0.0
        for i in range(6):
            nrm += dq[i] * dq[i]
        nrm = math.sqrt(nrm)
        if not np.isfinite(nrm):
            return q, False, it
        lim = 0.25 * lmin
        f = 1.0 if nrm <= lim else lim / nrm
        for i in range(6):
            q[i] += f * dq[i]
        p = radial_project(q[0], q[1], q[2], sh1)
        q[0], q[1], q[2] = p[0], p[1], p[2]
        p = radial_project(q[3], q[4], q[5], sh2)
        q[3], q[4], q[5] = p[0], p[1], p[2]
        if nrm < tol * L:
            return q, True, it + 1
    return q, False, maxit


@njit(cache=True)
def _g_dir(d0, d1, d2, sh1, r1, A1, sh2, r2, A2):
    l1 = mat_t_vec(A1, d0, d1, d2)
    l2 = mat_t_vec(A2, -d0, -d1, -d2)
    h1 = d0 * r1[0] + d1 * r1[1] + d2 * r1[2] + support_value_local(l1[0], l1[1], l1[2], sh1)
    h2 = -(d0 * r2[0] + d1 * r2[1] + d2 * r2[2]) + support_value_local(l2[0], l2[1], l2[2], sh2)
    return -(h1 + h2)


@njit(cache=True)
def seed(sh1, r1, A1, sh2, r2, A2, dirs, levels=8):
    """Best direction d of the signed-gap function g(d) = -(h1(d) + h2(-d)): the best of `dirs`, then
    `levels` rounds of a 5 x 5 tangent-plane grid around it (half-width 0.2 rad, shrinking x0.5).
    Returns (g_best, q0 = [sigma1_local(d); sigma2_local(-d)]); g_best <= the true signed gap."""
    best = -1e300
    ib = 0
    for k in range(dirs.shape[0]):
        g = _g_dir(dirs[k, 0], dirs[k, 1], dirs[k, 2], sh1, r1, A1, sh2, r2, A2)
        if g > best:
            best = g
            ib = k
    d0, d1, d2 = dirs[ib, 0], dirs[ib, 1], dirs[ib, 2]
    w = 0.2
    for _ in range(levels):
        # tangent basis of d
        if abs(d0) < 0.9:
            t0, t1, t2 = 0.0, d2, -d1
        else:
            t0, t1, t2 = -d2, 0.0, d0
        tn = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
        t0, t1, t2 = t0 / tn, t1 / tn, t2 / tn
        b0, b1, b2 = d1 * t2 - d2 * t1, d2 * t0 - d0 * t2, d0 * t1 - d1 * t0
        e0, e1, e2 = d0, d1, d2
        for i in range(-2, 3):
            for j in range(-2, 3):
                if i == 0 and j == 0:
                    continue
                c0 = d0 + 0.5 * w * (i * t0 + j * b0)
                c1 = d1 + 0.5 * w * (i * t1 + j * b1)
                c2 = d2 + 0.5 * w * (i * t2 + j * b2)
                cn = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
                c0, c1, c2 = c0 / cn, c1 / cn, c2 / cn
                g = _g_dir(c0, c1, c2, sh1, r1, A1, sh2, r2, A2)
                if g > best:
                    best = g
                    e0, e1, e2 = c0, c1, c2
        d0, d1, d2 = e0, e1, e2
        w *= 0.5
    l1 = mat_t_vec(A1, d0, d1, d2)
    l2 = mat_t_vec(A2, -d0, -d1, -d2)
    s1 = support_local(l1[0], l1[1], l1[2], sh1)
    s2 = support_local(l2[0], l2[1], l2[2], sh2)
    q0 = np.empty(6)
    q0[0], q0[1], q0[2] = s1[0], s1[1], s1[2]
    q0[3], q0[4], q0[5] = s2[0], s2[1], s2[2]
    return best, q0


@njit(cache=True)
def evaluate(q, sh1, r1, A1, sh2, r2, A2):
    """Gap, normal, points and acceptance of a converged pair. Returns
    (gap, n (3,), P (3,), Q (3,), ok)."""
    P = np.empty(3)
    Q = np.empty(3)
    p = mat_vec(A1, q[0], q[1], q[2])
    s = mat_vec(A2, q[3], q[4], q[5])
    for i in range(3):
        P[i] = r1[i] + p[i]
        Q[i] = r2[i] + s[i]
    nPl = normal_local(q[0], q[1], q[2], sh1)
    nQl = normal_local(q[3], q[4], q[5], sh2)
    nPt = mat_vec(A1, nPl[0], nPl[1], nPl[2])
    nQt = mat_vec(A2, nQl[0], nQl[1], nQl[2])
    n = np.empty(3)
    for i in range(3):
        n[i] = nPt[i]
    d0, d1, d2 = Q[0] - P[0], Q[1] - P[1], Q[2] - P[2]
    dist = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    sdot = n[0] * d0 + n[1] * d1 + n[2] * d2
    gap = dist if sdot > 0.0 else -dist
    ok = (nPt[0] * nQt[0] + nPt[1] * nQt[1] + nPt[2] * nQt[2]) <= -0.99
    if dist > 1e-9:
        c = sdot / dist
        if gap > 0.0:
            ok = ok and c >= 0.99 and (-(nQt[0] * d0 + nQt[1] * d1 + nQt[2] * d2) / dist) >= 0.99
        else:
            ok = ok and c <= -0.99 and ((nQt[0] * d0 + nQt[1] * d1 + nQt[2] * d2) / dist) >= 0.99
    return gap, n, P, Q, ok


# ----------------------------------------------------------------------------------------------------
# SLSQP fallback (Portal, Dias & Sousa, §12)
# ----------------------------------------------------------------------------------------------------
def _grad_G_global(x, sh, r, A):
    l = (x - r) @ A
    g = np.array(grad_G_local(l[0], l[1], l[2], sh))
    return A @ g


def portal_slsqp(sh1, r1, A1, sh2, r2, A2, x0, constraints="normals_dot", maxiter=200, ftol=1e-14):
    """Portal's constrained formulation solved by SLSQP from x0 = [P1; P2] (global).
    Returns (x, scipy result)."""
    def n1(x):
        return np.array(normal_global(x[0], x[1], x[2], sh1, r1, A1))

    def n2(x):
        return np.array(normal_global(x[3], x[4], x[5], sh2, r2, A2))

    def f(x):
        d = x[3:] - x[:3]
        return d @ d

    def df(x):
        d = x[3:] - x[:3]
        return np.concatenate([-2 * d, 2 * d])

    cons = [
        {"type": "eq", "fun": lambda x: G_global(x[0], x[1], x[2], sh1, r1, A1),
         "jac": lambda x: np.concatenate([_grad_G_global(x[:3], sh1, r1, A1), np.zeros(3)])},
        {"type": "eq", "fun": lambda x: G_global(x[3], x[4], x[5], sh2, r2, A2),
         "jac": lambda x: np.concatenate([np.zeros(3), _grad_G_global(x[3:], sh2, r2, A2)])},
    ]
    if constraints == "normals_dot":
        cons.append({"type": "eq", "fun": lambda x: n1(x) @ n2(x) + 1.0})
    elif constraints == "normals_cross":
        cons.append({"type": "eq", "fun": lambda x: np.cross(n1(x), n2(x))})
    else:
        raise ValueError(f"unknown constraint set {constraints!r} (use 'normals_dot' or 'normals_cross')")
    h1 = 1.1 * max(sh1[:3])
    h2 = 1.1 * max(sh2[:3])
    bounds = [(r1[k] - h1, r1[k] + h1) for k in range(3)] + [(r2[k] - h2, r2[k] + h2) for k in range(3)]
    x0 = np.clip(x0, [b[0] for b in bounds], [b[1] for b in bounds])
    res = minimize(f, x0, jac=df, method="SLSQP", constraints=cons, bounds=bounds,
                   options={"maxiter": maxiter, "ftol": ftol})
    return res.x, res


# ----------------------------------------------------------------------------------------------------
# public entry point
# ----------------------------------------------------------------------------------------------------
def _as(sh, r, A):
    return (np.ascontiguousarray(sh, dtype=np.float64), np.ascontiguousarray(r, dtype=np.float64),
            np.ascontiguousarray(A, dtype=np.float64))


def signed_gap(sh1, r1, A1, sh2, r2, A2, warm=None, info=None, method="auto",
               constraints="normals_dot"):
    """Signed gap between two convex superellipsoids (shape arrays, centres, rotation matrices).

    Returns (gap, normal, P1, P2, converged); see the module docstring. method: 'auto' (Newton, SLSQP
    fallback), 'newton' (no fallback), 'slsqp' (Portal's formulation only, then Newton polish)."""
    sh1, r1, A1 = _as(sh1, r1, A1)
    sh2, r2, A2 = _as(sh2, r2, A2)
    g_seed, q_seed = seed(sh1, r1, A1, sh2, r2, A2, SEED_DIRS)
    tol_seed = 1e-9 * max(sh1[:3].max(), sh2[:3].max())
    iters = 0
    if method in ("auto", "newton"):
        starts = []
        if warm is not None:
            starts.append(("newton-warm", np.asarray(warm, float)))
        starts.append(("newton", q_seed))
        for name, q0 in starts:
            q, conv, it = newton_common_normal(q0, sh1, r1, A1, sh2, r2, A2)
            iters += it
            if conv:
                gap, n, P, Q, ok = evaluate(q, sh1, r1, A1, sh2, r2, A2)
                if ok and gap >= g_seed - tol_seed and np.isfinite(gap):
                    return _out(gap, n, P, Q, True, info, name, iters, q)
        if method == "newton":
            gap, n, P, Q, ok = evaluate(q, sh1, r1, A1, sh2, r2, A2)
            return _out(gap, n, P, Q, False, info, "newton", iters, q)
    # fallback: Portal / SLSQP from the seed's support points, then Newton polish
    x0 = np.concatenate([r1 + A1 @ q_seed[:3], r2 + A2 @ q_seed[3:]])
    x, res = portal_slsqp(sh1, r1, A1, sh2, r2, A2, x0, constraints=constraints)
    qs = np.concatenate([(x[:3] - r1) @ A1, (x[3:] - r2) @ A2])
    q, conv, it = newton_common_normal(qs, sh1, r1, A1, sh2, r2, A2)
    iters += it
    if conv:
        gap, n, P, Q, ok = evaluate(q, sh1, r1, A1, sh2, r2, A2)
        if ok and gap >= g_seed - tol_seed and np.isfinite(gap):
            return _out(gap, n, P, Q, True, info, "slsqp", iters, q)
    gap, n, P, Q, ok = evaluate(qs, sh1, r1, A1, sh2, r2, A2)
    ok = bool(ok and res.success and gap >= g_seed - 1e-6)
    return _out(gap, n, P, Q, ok, info, "slsqp", iters + res.nit, qs)


def _out(gap, n, P, Q, conv, info, name, iters, q):
    if info is not None:
        info["method"] = name
        info["iterations"] = int(iters)
        info["warm"] = np.array(q)
    return float(gap), np.array(n), np.array(P), np.array(Q), bool(conv)


def gap_function(d, sh1, r1, A1, sh2, r2, A2):
    """g(d) = -(h1(d) + h2(-d)) for unit directions d (N, 3): the separation of the two bodies along d.
    The signed gap equals max_d g(d) (separating-axis theorem for convex bodies). Vectorised helper
    (used by the seed and the tests' brute force)."""
    d = np.atleast_2d(np.asarray(d, float))
    l1 = d @ A1
    l2 = -d @ A2
    h1 = d @ r1 + np.array([support_value_local(v[0], v[1], v[2], sh1) for v in l1])
    h2 = -(d @ r2) + np.array([support_value_local(v[0], v[1], v[2], sh2) for v in l2])
    return -(h1 + h2)
