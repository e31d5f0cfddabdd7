"""The plane-optimal light matrix and its pieces (Chong & Gortler, "A Lixel for every Pixel", EGSR 2004,
§2, Eq. 1 and 7-10), in the paper's notation: M_v the viewer's world -> clip matrix, l the light
(homogeneous, w = 0 for a sun), π the plane of interest (π·X = 0 on P). Derivation: docs/papers.md."""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from .geometry import cross
from .types import WarpError

RANK_TOL = 1e-10
"""The DLT system of Eq. 1, 7-10 must have rank 15: its 15th singular value over
its first must exceed this, else the five points are (nearly) degenerate."""

RESIDUAL_TOL = 1e-9
"""Largest accepted sine of the angle between M·X and its wanted image Y."""

LIGHT_TARGETS = np.array([[-1.0, -1.0, 1.0, 1.0], [-1.0, 1.0, 1.0, 1.0], [1.0, 1.0, 1.0, 1.0],
                          [1.0, -1.0, -1.0, 1.0], [0.0, 0.0, 1.0, 0.0]])
"""The light-image targets of p^1..p^3, p̂^4 (the view corners, light z +1, and
-1 for p̂^4) and of l (the centre of projection, sent to infinity along z)."""

FLAT_RATIO = 0.1
"""A receiver box is flat (a floor, a table top, terrain) when its height is at
most this fraction of its smaller horizontal side."""


@dataclass(frozen=True)
class PlaneOfInterest:
    """The plane ``normal · x = offset`` (unit normal), optionally limited to the convex
    ``extent`` polygon ((K, 3) on the plane); ``name`` for messages."""

    normal: np.ndarray
    offset: float
    extent: Optional[np.ndarray] = None
    name: str = "plane"

    @classmethod
    def through(cls, point, normal, extent=None, name: str = "plane") -> "PlaneOfInterest":
        n = np.asarray(normal, dtype=np.float64).reshape(3)
        p = np.asarray(point, dtype=np.float64).reshape(3)
        norm = float(np.linalg.norm(n))
        if not (np.all(np.isfinite(n)) and np.all(np.isfinite(p))) or norm == 0.0:
            raise WarpError(f"{name}: needs a finite point and a non-zero finite normal")
        n = n / norm
        ext = None
        if extent is not None:
            ext = np.asarray(extent, dtype=np.float64).reshape(-1, 3)
            if len(ext) < 3 or not np.all(np.isfinite(ext)):
                raise WarpError(f"{name}: an extent needs at least 3 finite points")
            ext = ext - np.outer(ext @ n - float(n @ p), n)  # onto the plane
        return cls(n, float(n @ p), ext, name)

    @classmethod
    def from_option(cls, entry, index: int) -> "PlaneOfInterest":
        """``WarpOptions.planes`` entries: (point, normal) or (point, normal, extent polygon)."""
        name = f"planes[{index}]"
        if isinstance(entry, PlaneOfInterest):
            return entry
        if isinstance(entry, dict):
            return cls.through(entry.get("point"), entry.get("normal"), entry.get("extent"), name)
        try:
            items = list(entry)
        except TypeError:
            items = []
        if len(items) not in (2, 3):
            raise WarpError(f"{name}: must be (point, normal) or (point, normal, extent)")
        return cls.through(*items, name=name)

    def vector(self, origin=None) -> np.ndarray:
        """π = (n, -offset) for coordinates relative to ``origin``: π·(x - origin, 1) = 0 on P."""
        o = 0.0 if origin is None else float(self.normal @ np.asarray(origin, dtype=np.float64))
        return np.append(self.normal, -(self.offset - o))


def five_point_matrix(src, dst) -> tuple[np.ndarray, dict]:
    """The 4x4 projective M with M·src_i ∝ dst_i for five homogeneous correspondences, no four coplanar (§2
    after Faugeras 1993), and {"condition", "residual"}; WarpError below rank 15 (RANK_TOL) or past RESIDUAL_TOL."""
    src = np.asarray(src, dtype=np.float64).reshape(5, 4)
    dst = np.asarray(dst, dtype=np.float64).reshape(5, 4)
    coefficients, dst_frame = _targets(dst.tobytes())
    a = (coefficients[:, :, None] * src.repeat(3, axis=0)[:, None, :]).reshape(15, 16)   # M's entries row by row
    if not np.isfinite(a).all():
        raise WarpError("the five point constraints are not finite")
    sv = np.linalg.svd(a, compute_uv=False)
    condition = float(sv[-1] / sv[0]) if sv[0] > 0 else 0.0
    if not condition > RANK_TOL:
        raise WarpError(f"the five point constraints are degenerate (rank < 15, relative singular value {condition:.3g})")
    m = dst_frame @ _frame_inverse(src)
    return m, {"condition": condition, "residual": _residual(m, src, dst)}


@functools.lru_cache(maxsize=8)
def _targets(dst_bytes: bytes) -> tuple[np.ndarray, np.ndarray]:
    """The DLT coefficients (15, 4) of the targets Y (Y_m for row j, -Y_j for row m of
    Y_m (M X)_j - Y_j (M X)_m) and their projective frame; made once per targets."""
    dst = np.frombuffer(dst_bytes).reshape(5, 4)
    coefficients = np.zeros((15, 4))
    for i, y in enumerate(dst):
        m = int(np.argmax(np.abs(y)))
        for e, j in enumerate(k for k in range(4) if k != m):
            coefficients[3 * i + e, j], coefficients[3 * i + e, m] = y[m], -y[j]
    return coefficients, np.linalg.inv(_frame_inverse(dst))


def _residual(m: np.ndarray, src: np.ndarray, dst: np.ndarray) -> float:
    """The largest distance between M·X and Y as unit vectors (of either sign)."""
    mx = src @ m.T
    mx_norm = np.linalg.norm(mx, axis=1)
    if np.any(mx_norm <= 1e-12 * np.linalg.norm(m) * np.linalg.norm(src, axis=1)):
        raise WarpError("the five point constraints are degenerate (the solution maps a constrained point to "
                        "nothing: four of the points are coplanar)")
    mx, y = mx / mx_norm[:, None], dst / np.linalg.norm(dst, axis=1)[:, None]
    residual = float(np.minimum(np.linalg.norm(mx - y, axis=1), np.linalg.norm(mx + y, axis=1)).max())
    if not residual <= RESIDUAL_TOL:
        raise WarpError(f"the five point solve missed its constraints (residual {residual:.3g})")
    return residual


def _frame_inverse(p: np.ndarray) -> np.ndarray:
    """F⁻¹ = diag(1/λ)·[p_1 .. p_4]⁻¹ for the projective frame F of five points (5, 4): F e_i ∝ p_i, F (1, 1, 1, 1) =
    p_5, its columns p_1..p_4 scaled by λ = [p_1 .. p_4]⁻¹ p_5 (Faugeras 1993). WarpError when four are coplanar."""
    try:
        columns_inverse = np.linalg.inv(p[:4].T)
    except np.linalg.LinAlgError:
        raise WarpError("the five point constraints are degenerate (four of the points are coplanar)") from None
    lam = columns_inverse @ p[4]
    if not (np.isfinite(lam).all() and np.abs(lam).min() > 0):
        raise WarpError("the five point constraints are degenerate (four of the points are coplanar)")
    return columns_inverse / lam[:, None]


def line_plane_points(a, b, plane_vec) -> np.ndarray:
    """Homogeneous (N, 4) points where the lines through a_i and b_i meet π: (π·b) a - (π·a) b (0 for a line in P)."""
    return (b @ plane_vec)[:, None] * a - (a @ plane_vec)[:, None] * b


VIEW_CORNER_RAYS = ((0, 2, 3, 1), (4, 6, 7, 5))
"""The view frustum's near and far corners (``View.corners()``) on the rays through
the image corners (-1, -1), (-1, 1), (1, 1), (1, -1) (Eq. 2's order)."""


def corner_ray_points(corners: np.ndarray, plane_vec) -> np.ndarray:
    """p^1..p^4: where the rays through the view's ``corners`` (``VIEW_CORNER_RAYS``) meet π, homogeneous."""
    near, far = (np.append(corners[list(ends)], np.ones((4, 1)), axis=1) for ends in VIEW_CORNER_RAYS)
    return line_plane_points(near, far, np.asarray(plane_vec, dtype=np.float64))


def plane_light_matrix(corner_points, light_h, length_scale: float) -> tuple[np.ndarray, dict]:
    """The light matrix of Eq. 1 and 7-10 from p^1..p^4 (``corner_points``) and l (``light_h``), relative to the
    camera: (4x4 M, info), or WarpError naming the reason."""
    points = np.asarray(corner_points, dtype=np.float64).reshape(4, 4).tolist()
    if not all(math.isfinite(c) for q in points for c in q) or min(math.hypot(*q) for q in points) <= 1e-300:
        raise WarpError("a corner ray of the view lies in the plane (the plane is seen edge-on)")
    # The spread of the finite p^i: their root mean square distance from the camera.
    dist = [math.hypot(x, y, z) / abs(w) for x, y, z, w in points if abs(w) > 1e-12 * math.hypot(x, y, z)]
    sigma = math.sqrt(sum(d * d for d in dist) / len(dist)) if dist else 0.0
    sigma = min(sigma, 1e6 * length_scale) if sigma > 0 else length_scale
    k = 1.0 / sigma                 # the normalising scale diag(k, k, k, 1), then each point of unit length
    src = [_unit_list([x * k, y * k, z * k, w]) for x, y, z, w in points + [list(map(float, light_h))]]
    src[3] = _unit_list([a + b for a, b in zip(src[3], src[4])])     # p̂^4: on the line through p^4 and l (Fig. 2)
    m, info = five_point_matrix(src, LIGHT_TARGETS)
    return m * np.array([k, k, k, 1.0]), info


def _unit_list(v: list) -> list:
    """``v`` scaled to unit length (unchanged if zero)."""
    n = math.hypot(*v)
    return [c / n for c in v] if n > 0 else v


def _clip_loop(pts: list, normal, offset: float, tol: float) -> list:
    """Sutherland-Hodgman in plain floats: the part of the convex polygon ``pts`` with normal · x <= offset."""
    nx, ny, nz = normal
    d = [nx * x + ny * y + nz * z - offset for x, y, z in pts]
    if max(d) <= tol:                                        # (nothing beyond the tolerance: nothing cut)
        return pts
    d = [0.0 if abs(e) <= tol else e for e in d]
    out = []
    for a, b, da, db in zip(pts, pts[1:] + pts[:1], d, d[1:] + d[:1]):
        if da <= 0:
            out.append(a)
        if (da < 0 < db) or (db < 0 < da):
            t = da / (da - db)
            out.append((a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])))
    return out


def clip_to_polygon(poly: np.ndarray, bound, normal, tol: float) -> Optional[np.ndarray]:
    """The part of the convex ``poly`` inside the convex ``bound`` on the same plane
    (CCW about ``normal``), or None when less than a triangle is left."""
    b = bound.tolist() if isinstance(bound, np.ndarray) else list(bound)
    pts = whole = poly.tolist()
    for (ax, ay, az), (ox, oy, oz) in zip(b, edge_normals(b, normal)):
        pts = _clip_loop(pts, (ox, oy, oz), ox * ax + oy * ay + oz * az, tol)
        if len(pts) < 3:
            return None
    return poly if pts is whole else np.array(pts, dtype=np.float64)      # (poly itself when no edge cut it)


def is_convex_polygon(points, normal, tol: float) -> bool:
    """Whether the points in order are a convex polygon CCW about ``normal`` that ``convex_polygon_on_plane`` keeps."""
    pts = np.asarray(points, dtype=np.float64).tolist()
    if len(pts) < 3:
        return False
    nx, ny, nz = (float(c) for c in normal)
    edges = [(bx - ax, by - ay, bz - az) for (ax, ay, az), (bx, by, bz) in zip(pts, pts[1:] + pts[:1])]
    perimeter = sum(math.hypot(*e) for e in edges)
    turned = 0.0
    for (ax, ay, az), (bx, by, bz) in zip(edges, edges[1:] + edges[:1]):
        left = (ay * bz - az * by) * nx + (az * bx - ax * bz) * ny + (ax * by - ay * bx) * nz
        if not left > tol * perimeter:
            return False
        turned += math.atan2(left, ax * bx + ay * by + az * bz)
    return abs(turned - 2 * math.pi) < 1e-6


def polygon_area(poly, normal) -> float:
    """The area of a planar polygon ((K, 3) vertices) with the unit ``normal``."""
    pts = np.asarray(poly, dtype=np.float64)
    return 0.5 * abs(float(cross(pts, np.concatenate([pts[1:], pts[:1]])).sum(axis=0) @ np.asarray(normal, dtype=np.float64)))


def offset_directions(poly, normal) -> np.ndarray:
    """Per vertex of the convex polygon, how it moves when every edge moves out by 1
    (the polygon grown by d, as ``Region.contains`` accepts it with tolerance d)."""
    out_n = edge_normals(np.asarray(poly, dtype=np.float64).tolist(), normal)
    out = []
    for n1, n2 in zip(out_n[-1:] + out_n[:-1], out_n):      # the edges before and after each vertex
        s = 1.0 + n1[0] * n2[0] + n1[1] * n2[1] + n1[2] * n2[2]
        if s > 1e-9:
            out.append([(a + b) / s for a, b in zip(n1, n2)])
        else:                                                # the polygon turns back on itself there
            m = [a + b for a, b in zip(n1, n2)]
            out.append(_unit_list(m if any(m) else list(n1)))
    return np.array(out).reshape(-1, 3)


def edge_normals(pts: list, normal) -> list:
    """Per edge of a convex polygon (a list, CCW about ``normal``): its outward unit
    normal on the plane, edge x normal (zero for an edge of no length)."""
    nx, ny, nz = (float(c) for c in normal)
    out = []
    for (ax, ay, az), (bx, by, bz) in zip(pts, pts[1:] + pts[:1]):
        ex, ey, ez = bx - ax, by - ay, bz - az
        norm = math.sqrt(ex * ex + ey * ey + ez * ez)
        if norm > 0:
            ex, ey, ez = ex / norm, ey / norm, ez / norm
        out.append((ey * nz - ez * ny, ez * nx - ex * nz, ex * ny - ey * nx))
    return out


def enclosing_polygon(poly: np.ndarray, normal: np.ndarray, max_vertices: int) -> np.ndarray:
    """A convex polygon of at most ``max_vertices`` containing the convex ``poly``:
    edges removed one at a time by extending their neighbours, the least added area first."""
    p, n = np.asarray(poly, dtype=np.float64), np.asarray(normal, dtype=np.float64)
    while len(p) > max(max_vertices, 3):
        a0, a1, b0, b1 = (np.roll(p, -shift, axis=0) for shift in (-1, 0, 1, 2))   # edge a1 -> b0 is removed
        d1, d2 = a1 - a0, b1 - b0
        turn = cross(d1, d2) @ n
        meet = turn > 1e-15 * np.linalg.norm(d1, axis=1) * np.linalg.norm(d2, axis=1)    # beyond the edge
        if not meet.any():
            break
        with np.errstate(divide="ignore", invalid="ignore"):
            x = a0 + ((cross(b0 - a0, d2) @ n) / turn)[:, None] * d1
        added = np.where(meet, np.abs(cross(x - a1, b0 - a1) @ n), np.inf)        # twice the area each adds
        i, k = int(np.argmin(added)), len(p)
        p = np.insert(np.delete(p, [i, (i + 1) % k], axis=0), i if i + 2 < k else 0, x[i], axis=0)
    return p


def min_area_twist(points2d: np.ndarray) -> float:
    """The rotation θ in (-π/4, π/4] giving the points' smallest axis-aligned rectangle (rotating calipers)."""
    p = np.asarray(points2d, dtype=np.float64).reshape(-1, 2)
    e = np.roll(p, -1, axis=0) - p
    e = e[e.any(axis=1)]                                   # each edge of some length gives one candidate
    if not len(e):
        return 0.0
    theta = (math.pi / 4 - np.arctan2(e[:, 1], e[:, 0])) % (math.pi / 2) - math.pi / 4
    c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
    area = np.ptp(c * p[:, 0] - s * p[:, 1], axis=1) * np.ptp(s * p[:, 0] + c * p[:, 1], axis=1)
    return float(theta[np.argmax(area <= area.min() * (1 + 1e-12))])     # the first of the least (to rounding)


def rotation2d(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def _flat_tops(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per box ((3, ...) corner arrays): its top's area if flat (height <= FLAT_RATIO x
    its smaller side), else -1; and its height."""
    ext = hi - lo
    side = np.minimum(ext[0], ext[1])
    flat = (side > 0) & (ext[2] <= FLAT_RATIO * side)
    return np.where(flat, ext[0] * ext[1], -1.0), ext[2]


def _top_face(lo, hi, i: int) -> PlaneOfInterest:
    """The top face of receiver box ``i`` (corners ``lo``, ``hi``) as a plane of interest limited to it."""
    (x0, y0, _), (x1, y1, top) = lo, hi
    face = np.array([[x0, y0, top], [x1, y0, top], [x1, y1, top], [x0, y1, top]], dtype=np.float64)
    return PlaneOfInterest(np.array([0.0, 0.0, 1.0]), float(top), face, f"top of receiver box {i}")


def flattest_box(receiver_boxes) -> Optional[tuple[int, float, float]]:
    """(index, height, smaller side) of the receiver box nearest to flat, or None."""
    ext = np.diff(np.asarray(receiver_boxes, dtype=np.float64).reshape(-1, 2, 3), axis=1)[:, 0]
    side = np.minimum(ext[:, 0], ext[:, 1])
    if not (side > 0).any():
        return None
    i = int(np.argmin(np.where(side > 0, ext[:, 2] / np.where(side > 0, side, 1.0), np.inf)))
    return i, float(ext[i, 2]), float(side[i])


def top_shares(boxes, surface: np.ndarray, tol: float) -> np.ndarray:
    """Per box, the share of the seen surface (``VisibleRegion.surface``) on its top face: the samples whose depth
    interval meets the top's height and whose middle lies over the box, within ``tol``."""
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 2, 3)
    order = np.argsort(b[:, 1, 2], kind="stable")
    z, tops = np.sort(surface[:, :, 2], axis=1), b[order, 1, 2]
    first = np.searchsorted(tops, z[:, 0] - tol)
    count = np.searchsorted(tops, z[:, 1] + tol, "right") - first          # per sample: the tops its depths meet
    seen = np.zeros(len(b))
    for part in np.array_split(np.arange(len(z)), 1 + (int(count.sum()) >> 22)):      # (~4M sample-top pairs at once)
        c = count[part]
        box = order[np.repeat(first[part] - np.cumsum(c) + c, c) + np.arange(c.sum())]
        mid = surface[np.repeat(part, c)].mean(axis=1)[:, :2]
        over = ((mid >= b[box, 0, :2] - tol) & (mid <= b[box, 1, :2] + tol)).all(axis=1)
        seen += np.bincount(box[over], minlength=len(b))
    return seen / max(len(z), 1)


def default_plane(receiver_boxes, surface: Optional[np.ndarray] = None, tol: float = 0.0,
                  at_edges: Optional[np.ndarray] = None) -> tuple[Optional[PlaneOfInterest], Optional[float]]:
    """The default plane of interest and its seen share: the flat receiver top the ``surface`` is most on
    (``top_shares``; on none: None), without a surface the widest (share None); then widest, thinnest, first. Given
    ``at_edges`` (which samples lie at a shadow edge; none: no evidence), the top's share of those samples instead."""
    b = np.asarray(receiver_boxes, dtype=np.float64).reshape(-1, 2, 3)
    area, height = _flat_tops(b[:, 0].T, b[:, 1].T)
    share = np.zeros(len(b)) if surface is None else top_shares(b, surface, tol)
    for i in np.lexsort((np.arange(len(b)), height, -area, -np.where(area >= 0, share, -1.0)))[:1].tolist():
        if area[i] >= 0 and (surface is None or share[i] > 0):
            edges = share[i:i + 1] if not np.any(at_edges) else top_shares(b[i:i + 1], surface[at_edges], tol)
            return _top_face(b[i, 0], b[i, 1], i), None if surface is None else float(edges[0])
    return None, None
