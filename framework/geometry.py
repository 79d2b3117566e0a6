"""Planar geometry of vehicle outlines and barriers (rectangles), shared by every planar model.

The functions are plain Python on scalars and small arrays, registered with numba so that the
compiled impulse kernel calls the very same code (`register_jitable`): one home for the geometry.
"""
import math

import numpy as np
from numba.extending import register_jitable


@register_jitable
def rect_corners(x, y, heading, front, rear, half_width):
    """Corners (4, 2), counter-clockwise, of a rectangle reaching `front` ahead of and `rear` behind
    its reference point (x, y) along `heading` [rad], `half_width` to each side."""
    return rect_corners_into(np.empty((4, 2)), x, y, math.cos(heading), math.sin(heading), front, rear, half_width)


def rect_overlap_rows(r1, r2):
    """N pairs of rectangles at once: the least, over the four edge normals n (separating axes), of the sum of
    their projections' half lengths less their centres' distance along n (how far to push them apart along n):
    > 0 exactly where they overlap, as penetration's depth (which is capped at the shorter projection). A
    rectangle r is (x, y, heading, front, rear, half_width) as rect_corners' arguments, scalars or (N,) arrays."""
    (x1, y1, h1, f1, b1, w1), (x2, y2, h2, f2, b2, w2) = r1, r2
    c1, s1, c2, s2 = np.cos(h1), np.sin(h1), np.cos(h2), np.sin(h2)
    m1, m2 = 0.5 * (np.asarray(f1) - b1), 0.5 * (np.asarray(f2) - b2)  # the centres ahead of the reference points
    dx = x2 + m2 * c2 - x1 - m1 * c1
    dy = y2 + m2 * s2 - y1 - m1 * s1
    a1, a2 = 0.5 * (np.asarray(f1) + b1), 0.5 * (np.asarray(f2) + b2)
    cc, cs = np.abs(c1 * c2 + s1 * s2), np.abs(c1 * s2 - s1 * c2)  # |cos|, |sin| of the angle between them
    return np.minimum.reduce([
        a1 + a2 * cc + w2 * cs - np.abs(dx * c1 + dy * s1),    # along rectangle 1's length
        w1 + a2 * cs + w2 * cc - np.abs(-dx * s1 + dy * c1),   # across it
        a2 + a1 * cc + w1 * cs - np.abs(dx * c2 + dy * s2),    # along rectangle 2's length
        w2 + a1 * cs + w1 * cc - np.abs(-dx * s2 + dy * c2)])  # across it


@register_jitable
def rect_corners_into(out, x, y, c, s, front, rear, half_width):
    """rect_corners with the heading's cosine and sine (c, s) given, written into `out` (4, 2) and returned:
    no allocation and no trigonometry of its own in a compiled loop."""
    local = ((front, -half_width), (front, half_width), (-rear, half_width), (-rear, -half_width))
    for i in range(4):
        lx, ly = local[i]
        out[i, 0] = x + c * lx - s * ly
        out[i, 1] = y + s * lx + c * ly
    return out


@register_jitable
def _project(corners, ax, ay):
    lo, hi = 1e300, -1e300
    for i in range(corners.shape[0]):
        p = corners[i, 0] * ax + corners[i, 1] * ay
        lo = min(lo, p)
        hi = max(hi, p)
    return lo, hi


@register_jitable
def penetration(c1, c2):
    """Separating-axis test of two convex quadrilaterals (corners counter-clockwise).

    Returns (depth, nx, ny, owner): depth > 0 is the overlap along the axis of least overlap, depth <= 0
    the largest separation found (a lower bound of the distance); n is that axis, unit, oriented from
    outline 1 to outline 2; owner is 1 or 2, the outline whose edge defines the axis (the struck edge).
    """
    best, bnx, bny, owner = 1e300, 0.0, 0.0, 0
    for k in range(2):
        poly = c1 if k == 0 else c2
        for i in range(4):
            j = (i + 1) % 4
            ex, ey = poly[j, 0] - poly[i, 0], poly[j, 1] - poly[i, 1]
            norm = math.hypot(ex, ey)
            ax, ay = ey / norm, -ex / norm  # outward normal of a counter-clockwise edge
            lo1, hi1 = _project(c1, ax, ay)
            lo2, hi2 = _project(c2, ax, ay)
            overlap = min(hi1, hi2) - max(lo1, lo2)
            if overlap < best:
                best = overlap
                sign = 1.0 if (lo2 + hi2) - (lo1 + hi1) >= 0.0 else -1.0
                bnx, bny, owner = sign * ax, sign * ay, k + 1
    return best, bnx, bny, owner


@register_jitable
def clip_convex(subject, clip):
    """Sutherland-Hodgman: the part of convex polygon `subject` inside convex `clip` (both CCW).
    Returns (points, n): the first n rows of points hold the overlap polygon."""
    buf = np.empty((16, 2))
    nxt = np.empty((16, 2))
    n = subject.shape[0]
    buf[:n] = subject
    m = clip.shape[0]
    for e in range(m):
        ax, ay = clip[e, 0], clip[e, 1]
        bx, by = clip[(e + 1) % m, 0], clip[(e + 1) % m, 1]
        k = 0
        for i in range(n):
            px, py = buf[i, 0], buf[i, 1]
            qx, qy = buf[(i + 1) % n, 0], buf[(i + 1) % n, 1]
            sp = (bx - ax) * (py - ay) - (by - ay) * (px - ax)  # >= 0: left of the edge, inside
            sq = (bx - ax) * (qy - ay) - (by - ay) * (qx - ax)
            if sp >= 0.0:
                nxt[k, 0], nxt[k, 1] = px, py
                k += 1
            if (sp >= 0.0) != (sq >= 0.0) and k < 16:
                t = sp / (sp - sq)
                nxt[k, 0], nxt[k, 1] = px + t * (qx - px), py + t * (qy - py)
                k += 1
        n = k
        buf[:n] = nxt[:n]
        if n == 0:
            break
    return buf, n


@register_jitable
def overlap_centroid(c1, c2):
    """Centroid (x, y) and area of the overlap of two convex outlines; for a sliver of (near) zero area
    the mean of its vertices, i.e. the middle of the contact segment."""
    pts, n = clip_convex(c1, c2)
    if n == 0:
        return math.nan, math.nan, 0.0
    area, cx, cy = 0.0, 0.0, 0.0
    mx, my = 0.0, 0.0
    for i in range(n):
        j = (i + 1) % n
        cr = pts[i, 0] * pts[j, 1] - pts[j, 0] * pts[i, 1]
        area += cr
        cx += (pts[i, 0] + pts[j, 0]) * cr
        cy += (pts[i, 1] + pts[j, 1]) * cr
        mx += pts[i, 0]
        my += pts[i, 1]
    area *= 0.5
    if abs(area) < 1e-9:
        return mx / n, my / n, abs(area)
    return cx / (6.0 * area), cy / (6.0 * area), abs(area)


@register_jitable
def contact_zone_centroid(c1, c2, nx, ny, depth):
    """Middle of the contact zone of two touching outlines: the centroid of their overlap once outline 2
    is pushed `depth` further along -n (n unit, from 1 to 2, e.g. `penetration`'s axis), moved back by
    depth / 2 along n so it lies between the two crush zones. For parallel faces this is the middle of
    the common face segment, as `overlap_centroid` at first touch; for faces at an angle theta it moves
    smoothly from the touching corner (depth 0) to inside a zone of length ~depth / tan(theta), so the
    point of impact no longer jumps when theta passes through zero. Returns (x, y, area)."""
    moved = c2.copy()
    for i in range(moved.shape[0]):
        moved[i, 0] -= depth * nx
        moved[i, 1] -= depth * ny
    x, y, area = overlap_centroid(c1, moved)
    return x + 0.5 * depth * nx, y + 0.5 * depth * ny, area


@register_jitable
def _on_boundary(outline, x, y, tol):
    """(x, y) lies within tol of one of the edges' lines of the convex outline (and so on its boundary, for
    a point of an overlap polygon's edge, which lies inside or on the outline)."""
    m = outline.shape[0]
    for e in range(m):
        ax, ay = outline[e, 0], outline[e, 1]
        bx, by = outline[(e + 1) % m, 0], outline[(e + 1) % m, 1]
        length = math.hypot(bx - ax, by - ay)
        if length > 0.0 and abs((bx - ax) * (y - ay) - (by - ay) * (x - ax)) <= tol * length:
            return True
    return False


@register_jitable
def crushed_faces_axis(poly, n, dx, dy, rigid):
    """The direction along the crushed faces of an overlap polygon (its first n rows, poly (m, 2)) made by
    moving one outline by (dx, dy) against the other (docs/physics.md §4). Each edge of the polygon is a
    piece of one outline's face pushed into the other; it is weighted by the area it swept, |edge x d|
    (its length times its crush depth: a face along d crushes nothing), and the direction is the principal
    axis of sum w t t^T over the edges' unit directions t (their doubled-angle mean): midway between two
    faces of equal weight, i.e. the surface where two equally stiff structures meet. rigid: the outline of
    a partner that does not crush (a barrier), whose faces alone then count (the crushed car ends up along
    them), or an empty (0, 2) array. Returns (tx, ty, ratio): the unit direction and the smaller principal
    value over the larger (0: every crushed face along one line, 1: no direction stands out); NaN where
    nothing was swept."""
    c2, s2, w_sum = 0.0, 0.0, 0.0
    for q in range(n):
        x0, y0 = poly[q, 0], poly[q, 1]
        ex, ey = poly[(q + 1) % n, 0] - x0, poly[(q + 1) % n, 1] - y0
        ll = ex * ex + ey * ey
        w = abs(ex * dy - ey * dx)
        if ll <= 0.0 or w <= 0.0:
            continue
        if rigid.shape[0] > 0 and not _on_boundary(rigid, x0 + 0.5 * ex, y0 + 0.5 * ey, 1e-9):
            continue
        c2 += w * (ex * ex - ey * ey) / ll  # w cos 2 theta
        s2 += w * 2.0 * ex * ey / ll  # w sin 2 theta
        w_sum += w
    if w_sum <= 0.0:
        return math.nan, math.nan, math.nan
    r = math.hypot(c2, s2)
    phi = 0.5 * math.atan2(s2, c2)
    return math.cos(phi), math.sin(phi), (w_sum - r) / (w_sum + r)
