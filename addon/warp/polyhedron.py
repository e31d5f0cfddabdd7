"""Convex polyhedra as face lists, clipped by half-spaces (float64, deterministic).

A polyhedron is a list of planar convex faces, each an ordered (K, 3) array of
points (outward counter-clockwise). Clipping by ``n . x <= o`` is Sutherland-
Hodgman on every face plus one cap face on the plane, so a clipped body is never
left open. Tolerances are always passed in, relative to the scene's scale.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Plane:
    """The half-space ``normal . x <= offset`` (normal of unit length)."""

    normal: np.ndarray
    offset: float

    def distance(self, points) -> np.ndarray:
        return np.asarray(points, dtype=np.float64) @ self.normal - self.offset

    @classmethod
    def through(cls, point, normal) -> "Plane":
        n = np.asarray(normal, dtype=np.float64)
        n = n / np.linalg.norm(n)
        return cls(n, float(n @ np.asarray(point, dtype=np.float64)))


def box_faces(lo, hi) -> list[np.ndarray]:
    """The six faces of the box [lo, hi], outward counter-clockwise."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    c = np.array([[hi[0] if i & 1 else lo[0], hi[1] if i & 2 else lo[1], hi[2] if i & 4 else lo[2]] for i in range(8)])
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    return [c[list(q)] for q in quads]


def hexahedron_faces(corners) -> list[np.ndarray]:
    """Faces of a hexahedron given as 8 corners ordered like geometry.UNIT_CUBE_CORNERS
    (near face first, x fastest then y) - e.g. a view frustum."""
    c = np.asarray(corners, dtype=np.float64)
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    return [c[list(q)] for q in quads]


def _polygon_on_plane(points: np.ndarray, normal: np.ndarray, tol: float) -> np.ndarray | None:
    """Convex hull (ordered CCW about ``normal``) of points lying on one plane."""
    pts = unique_points(points, tol)
    if len(pts) < 3:
        return None
    centre = pts.mean(axis=0)
    u = pts[np.argmax(np.linalg.norm(pts - centre, axis=1))] - centre
    if np.linalg.norm(u) <= tol:
        return None
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    xy = np.stack([(pts - centre) @ u, (pts - centre) @ v], axis=1)
    order = np.lexsort((xy[:, 1], xy[:, 0]))
    xy, pts = xy[order], pts[order]

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    # Andrew's monotone chain, dropping collinear points within tolerance.
    area_tol = tol * max(float(np.ptp(xy, axis=0).max()), tol)
    lower: list[int] = []
    for i in range(len(xy)):
        while len(lower) >= 2 and cross(xy[lower[-2]], xy[lower[-1]], xy[i]) <= area_tol:
            lower.pop()
        lower.append(i)
    upper: list[int] = []
    for i in reversed(range(len(xy))):
        while len(upper) >= 2 and cross(xy[upper[-2]], xy[upper[-1]], xy[i]) <= area_tol:
            upper.pop()
        upper.append(i)
    hull = lower[:-1] + upper[:-1]
    if len(hull) < 3:
        return None
    return pts[hull]


def unique_points(points, tol: float) -> np.ndarray:
    """Points merged within ``tol`` (first occurrence wins), in a deterministic
    lexicographic order."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(p) == 0:
        return p
    p = p[np.lexsort((p[:, 2], p[:, 1], p[:, 0]))]
    keep: list[np.ndarray] = []
    for q in p:
        if not keep or np.min(np.linalg.norm(np.asarray(keep) - q, axis=1)) > tol:
            keep.append(q)
    return np.asarray(keep)


def clip_faces(faces: list[np.ndarray], plane: Plane, tol: float) -> list[np.ndarray]:
    """Clip a closed convex polyhedron by a half-space, capping the cut."""
    out: list[np.ndarray] = []
    cut: list[np.ndarray] = []
    n, o = plane.normal, plane.offset
    for poly in faces:
        d = poly @ n - o
        d = np.where(np.abs(d) <= tol, 0.0, d)
        if np.all(d <= 0):
            out.append(poly)
            cut.extend(poly[d == 0])
            continue
        if np.all(d >= 0):
            cut.extend(poly[d == 0])
            continue
        kept: list[np.ndarray] = []
        k = len(poly)
        for i in range(k):
            a, b = poly[i], poly[(i + 1) % k]
            da, db = d[i], d[(i + 1) % k]
            if da <= 0:
                kept.append(a)
                if da == 0:
                    cut.append(a)
            if (da < 0 < db) or (db < 0 < da):
                t = da / (da - db)
                x = a + t * (b - a)
                kept.append(x)
                cut.append(x)
        face = _polygon_on_plane(np.asarray(kept), _face_normal(poly), tol)
        if face is not None:
            out.append(face)
    if out and cut:
        cap = _polygon_on_plane(np.asarray(cut), n, tol)
        if cap is not None:
            out.append(cap)
    return out if len(out) >= 4 else []


def _face_normal(poly: np.ndarray) -> np.ndarray:
    """Newell's normal of a planar polygon (outward for CCW order)."""
    n = np.zeros(3)
    for i in range(len(poly)):
        a, b = poly[i], poly[(i + 1) % len(poly)]
        n += np.array([(a[1] - b[1]) * (a[2] + b[2]), (a[2] - b[2]) * (a[0] + b[0]), (a[0] - b[0]) * (a[1] + b[1])])
    norm = np.linalg.norm(n)
    return n / norm if norm > 0 else n


def face_planes(faces: list[np.ndarray]) -> list[Plane]:
    """Outward half-spaces of the faces of a closed convex polyhedron."""
    centre = np.mean(np.concatenate(faces), axis=0)
    planes = []
    for f in faces:
        n = _face_normal(f)
        if not np.any(n):
            continue
        p = Plane(n, float(n @ f.mean(axis=0)))
        if p.distance(centre[None])[0] > 0:
            p = Plane(-n, -p.offset)
        planes.append(p)
    return planes


def face_edges(faces: list[np.ndarray], tol: float) -> list[tuple[np.ndarray, np.ndarray, int, int]]:
    """Edges (a, b, face i, face j) shared by two faces of a closed polyhedron."""
    verts = unique_points(np.concatenate(faces), tol)
    def idx(p):
        return int(np.argmin(np.linalg.norm(verts - p, axis=1)))
    owner: dict[tuple[int, int], list[int]] = {}
    for fi, f in enumerate(faces):
        ids = [idx(p) for p in f]
        for k in range(len(ids)):
            a, b = ids[k], ids[(k + 1) % len(ids)]
            if a != b:
                owner.setdefault((min(a, b), max(a, b)), []).append(fi)
    return [(verts[a], verts[b], fs[0], fs[1]) for (a, b), fs in sorted(owner.items()) if len(fs) >= 2]
