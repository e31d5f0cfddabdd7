"""Small float64 geometry helpers: 4x4 row-major matrices on column vectors
(``clip = M @ [x, y, z, 1]``), OpenGL NDC, eye spaces looking down local -Z, +Y up."""
from __future__ import annotations

import itertools
import math

import numpy as np

def cross(a, b) -> np.ndarray:
    """Cross products of 3-vectors along the last axis, (a × b)_i = ε_ijk a_j b_k."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if a.ndim == 1 and b.ndim == 1:
        (ax, ay, az), (bx, by, bz) = a.tolist(), b.tolist()
        return np.array([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx])
    return np.einsum("ijk,...j,...k->...i", LEVI_CIVITA, a, b)


LEVI_CIVITA = np.zeros((3, 3, 3))
LEVI_CIVITA[[0, 1, 2], [1, 2, 0], [2, 0, 1]], LEVI_CIVITA[[0, 2, 1], [2, 1, 0], [1, 0, 2]] = 1.0, -1.0


def dot3(a, b) -> float:
    """Dot product of two 3-vectors given as float sequences."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def across(v, d) -> list:
    """The float 3-vector ``v`` made perpendicular to the unit ``d``."""
    k = dot3(v, d)
    return [a - k * b for a, b in zip(v, d)]


def normalize(v) -> np.ndarray:
    """Unit vector along ``v`` (scaled first against over- and underflow); ValueError for zero or non-finite v."""
    v = np.asarray(v, dtype=np.float64)
    big = float(np.abs(v).max(initial=0.0))
    if not math.isfinite(big) or big == 0.0:
        raise ValueError(f"cannot normalize vector {v.tolist()}")
    if not 1e-150 < big < 1e150:
        v = v / big
    return v / (math.sqrt(v @ v) if v.ndim == 1 else float(np.linalg.norm(v)))


def homogeneous(points) -> np.ndarray:
    """(N, 3) points -> (N, 4) with w = 1."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    h = np.empty((len(p), 4))
    h[:, :3] = p
    h[:, 3] = 1.0
    return h


def point_runs(point_sets) -> tuple[np.ndarray, list, np.ndarray]:
    """Several non-empty (n_k, 3) point sets as one (N, 4) homogeneous array, the row
    each starts at and each row's set (the layout of ``transform_h_runs`` and ``fit.fit_runs``)."""
    counts = [len(p) for p in point_sets]
    starts = list(itertools.accumulate(counts[:-1], initial=0))
    points = point_sets[0] if len(point_sets) == 1 else np.concatenate(point_sets)
    return homogeneous(points), starts, np.repeat(np.arange(len(counts)), counts)


def transform_h_runs(matrices, points_h, run) -> np.ndarray:
    """Homogeneous points (N, 4), row i mapped by ``matrices[run[i]]`` (k, 4, 4); no divide."""
    if len(matrices) == 1:
        return points_h @ matrices[0].T
    return (points_h @ matrices.transpose(0, 2, 1))[run, np.arange(len(run))]


def transform_h(matrix, points) -> np.ndarray:
    """Apply a 4x4 matrix to (N, 3) points; returns homogeneous (N, 4), no divide."""
    return homogeneous(points) @ np.asarray(matrix, dtype=np.float64).T


def transform_points(matrix, points) -> np.ndarray:
    """Apply a 4x4 matrix to (N, 3) points with the homogeneous divide -> (N, 3)."""
    h = transform_h(matrix, points)
    return h[:, :3] / h[:, 3:4]


def raster_position(matrix, size, points) -> np.ndarray:
    """(N, 2) places of (N, 3) world ``points`` on the (width, height) ``size`` raster of the projective ``matrix``:
    NDC [-1, 1]² -> [0, size]², so ``floor`` is the texel's or pixel's (column, row); NaN where w <= 0."""
    h = transform_h(matrix, points)
    return (h[:, :2] / np.where(h[:, 3:] > 0, h[:, 3:], np.nan) * 0.5 + 0.5) * np.asarray(size, dtype=np.float64)


def translation(offset) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = offset
    return m


def perpendicular(v) -> np.ndarray:
    """A unit vector perpendicular to ``v``, away from the axis most aligned with it."""
    return normalize(cross(v, np.eye(3)[int(np.argmin(np.abs(v)))]))


def look_along(eye, forward, up_hint) -> np.ndarray:
    """World -> eye matrix for an eye at ``eye`` looking along ``forward`` (its -Z), +Y
    nearest ``up_hint`` (a deterministic perpendicular when they are parallel)."""
    f = normalize(forward)
    up = np.asarray(up_hint, dtype=np.float64)
    side = cross(f, up)
    if np.sqrt(side @ side) < 1e-9 * max(1.0, float(np.sqrt(up @ up))):
        side = cross(f, perpendicular(f))
    x = normalize(side)
    y = cross(x, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = x, y, -f
    m[:3, 3] = -m[:3, :3] @ np.asarray(eye, dtype=np.float64)
    return m


def depth_coefficients(near: float, far: float) -> tuple[float, float]:
    """(A, B) of the OpenGL perspective: z_gl = A z + B, w = -z, A = -(f + n)/(f - n), B = -2fn/(f - n)."""
    return -(far + near) / (far - near), -2 * far * near / (far - near)


def frustum_matrix(left, right, bottom, top, near, far) -> np.ndarray:
    """OpenGL glFrustum: eye space (looking down -Z) -> clip, near -> z_ndc -1."""
    m = np.zeros((4, 4))
    m[0, 0] = 2 * near / (right - left)
    m[0, 2] = (right + left) / (right - left)
    m[1, 1] = 2 * near / (top - bottom)
    m[1, 2] = (top + bottom) / (top - bottom)
    m[2, 2], m[2, 3] = depth_coefficients(near, far)
    m[3, 2] = -1.0
    return m


def perspective_matrix(fov_y, aspect, near, far) -> np.ndarray:
    """OpenGL gluPerspective with the vertical field of view ``fov_y`` in radians."""
    t = near * np.tan(fov_y / 2)
    return frustum_matrix(-t * aspect, t * aspect, -t, t, near, far)


def ortho_matrix(left, right, bottom, top, near, far) -> np.ndarray:
    """OpenGL glOrtho: eye space (looking down -Z) -> clip."""
    m = np.eye(4)
    m[0, 0] = 2 / (right - left)
    m[0, 3] = -(right + left) / (right - left)
    m[1, 1] = 2 / (top - bottom)
    m[1, 3] = -(top + bottom) / (top - bottom)
    m[2, 2] = -2 / (far - near)
    m[2, 3] = -(far + near) / (far - near)
    return m


UNIT_CUBE_CORNERS = np.array([[x, y, z] for z in (-1.0, 1.0) for y in (-1.0, 1.0) for x in (-1.0, 1.0)])
"""The 8 corners of NDC [-1,1]^3: near face (z=-1) first, x fastest."""


def clip_volume_corners(matrix) -> np.ndarray:
    """World-space corners of the clip volume of ``matrix`` (the NDC unit cube unprojected), ordered like
    ``UNIT_CUBE_CORNERS``; callers check ``np.isfinite``."""
    h = clip_volume_corners_h(matrix)
    return h[:, :3] / h[:, 3:]


def finite_clip_volume_corners(matrix, origin=0.0) -> np.ndarray | None:
    """``clip_volume_corners`` moved by ``origin`` (a camera-relative ``matrix``'s), or None where the volume
    reaches infinity (w <= 0 at a corner, to round-off) or ``matrix`` is singular."""
    try:
        h = clip_volume_corners_h(matrix)
    except np.linalg.LinAlgError:
        return None
    w = h[:, 3]
    if not np.all(np.isfinite(h)) or np.any(w <= 1e-12 * np.abs(h[:, :3]).max(axis=1)):
        return None
    return h[:, :3] / w[:, None] + origin


def clip_halfspaces(matrix) -> tuple[np.ndarray, np.ndarray]:
    """The world points ``matrix`` maps into its clip volume (-w <= x, y, z <= w; w > 0 follows), bounded or not, as
    six half-spaces ``normals @ x <= offsets``."""
    m = np.asarray(matrix, dtype=np.float64)
    rows = np.array([m[r] * s - m[3] for r in range(3) for s in (1.0, -1.0)])
    return rows[:, :3], -rows[:, 3]


def clip_volume_corners_h(matrix) -> np.ndarray:
    """The clip volume's corners as homogeneous world points (8, 4) (w <= 0: at infinity); LinAlgError when singular."""
    return _UNIT_CUBE_CORNERS_H @ np.linalg.inv(np.asarray(matrix, dtype=np.float64)).T


_UNIT_CUBE_CORNERS_H = homogeneous(UNIT_CUBE_CORNERS)
