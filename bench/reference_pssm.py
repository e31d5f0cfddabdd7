"""A reference 3-split PSSM, the classic an engine ships, to judge Lixel's cascade against.

Zhang et al.'s parallel-split shadow maps with the practical split scheme
(λ = 0.5) and a *uniform* map per split, written without Lixel's warp core
(no B, no light frames, no fitting helpers), the way an engine does it:

* the splits cut the camera's clip range, tightened to the depth range of the
  scene's bounding box (engines clip the cascades to the scene);
* each split's region is its slab of the view frustum clipped to the scene's
  bounding box;
* a sun's map is orthographic along the light, its image rectangle the
  region's in the light's image plane (the image's up is the view direction
  across the light), its depth range reaching back to the scene's box so
  every caster is in it;
* a point or spot light's map is the light's perspective around the
  region's directions, its near plane close to the light (every caster
  between the light and the region is held); when the region surrounds the
  light, six 90° cube faces aligned with the world axes instead.

Each map carries its split's ``view_depth_range``. Numpy only.
"""
from __future__ import annotations

import itertools
import math

import numpy as np

from addon.warp.types import Diagnostics, Light, SceneBounds, ShadowMap, ShadowSetup, View

BOX_CORNERS = np.array(list(itertools.product((0, 1), repeat=3)))
BOX_EDGES = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]
FRUSTUM_EDGES = [(0, 1), (2, 3), (4, 5), (6, 7), (0, 2), (1, 3), (4, 6), (5, 7), (0, 4), (1, 5), (2, 6), (3, 7)]
"""Edges of the 8 corners in x-fastest, then y, then z order (the view's corner order)."""


def practical_splits(near: float, far: float, count: int, lam: float = 0.5) -> np.ndarray:
    i = np.arange(count + 1) / count
    return lam * near * (far / near) ** i + (1 - lam) * (near + (far - near) * i)


def _split_corners(view: View, a: float, b: float) -> np.ndarray:
    """The 8 world corners of the view frustum's slab between eye depths a and b."""
    corners = view.corners()                    # near face (x fastest, then y), then far face
    eye = view.position
    out = []
    for depth in (a, b):
        for c_near, c_far in zip(corners[:4], corners[4:]):
            d_near, d_far = view.eye_depth(c_near[None])[0], view.eye_depth(c_far[None])[0]
            t = (depth - d_near) / (d_far - d_near)
            out.append(c_near + t * (c_far - c_near))
    del eye
    return np.array(out)


def _frustum_planes(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Outward (normals, offsets) of the hexahedron with these 8 corners."""
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    centre = corners.mean(axis=0)
    normals, offsets = [], []
    for f in faces:
        p = corners[list(f)]
        n = np.cross(p[1] - p[0], p[2] - p[0])
        n /= np.linalg.norm(n)
        if n @ (p[0] - centre) < 0:
            n = -n
        normals.append(n)
        offsets.append(n @ p[0])
    return np.array(normals), np.array(offsets)


def clipped_to_box(corners: np.ndarray, box: np.ndarray) -> np.ndarray:
    """Points whose convex hull is the hexahedron ``corners`` ∩ the box ``box``
    ((2, 3) min, max): corners inside the other, and edges crossing faces."""
    lo, hi = box
    scale = float(np.linalg.norm(hi - lo) + np.linalg.norm(corners.max(0) - corners.min(0)))
    tol = 1e-9 * scale
    normals, offsets = _frustum_planes(corners)
    box_pts = lo + BOX_CORNERS * (hi - lo)
    pts = [corners[np.all((corners >= lo - tol) & (corners <= hi + tol), axis=1)],
           box_pts[np.all(box_pts @ normals.T - offsets <= tol, axis=1)]]
    for a, b in FRUSTUM_EDGES:                   # frustum edges against the box's slabs
        p, q = corners[a], corners[b]
        for axis in range(3):
            for v in (lo[axis], hi[axis]):
                if (p[axis] - v) * (q[axis] - v) < 0:
                    pts.append((p + (v - p[axis]) / (q[axis] - p[axis]) * (q - p))[None])
    for a, b in BOX_EDGES:                       # box edges against the frustum's planes
        p, q = box_pts[a], box_pts[b]
        dp, dq = p @ normals.T - offsets, q @ normals.T - offsets
        for k in np.flatnonzero(dp * dq < 0):
            pts.append((p + dp[k] / (dp[k] - dq[k]) * (q - p))[None])
    pts = np.concatenate(pts)
    inside = np.all(pts @ normals.T - offsets <= tol * 10, axis=1) & np.all((pts >= lo - tol * 10) & (pts <= hi + tol * 10), axis=1)
    return pts[inside]


def _look(eye, forward, up) -> np.ndarray:
    f = forward / np.linalg.norm(forward)
    x = np.cross(f, up)
    if np.linalg.norm(x) < 1e-9:
        x = np.cross(f, np.eye(3)[int(np.argmin(np.abs(f)))])
    x /= np.linalg.norm(x)
    y = np.cross(x, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = x, y, -f
    m[:3, 3] = -m[:3, :3] @ eye
    return m


def _window(lo, hi) -> np.ndarray:
    pad = 1e-6 * (hi - lo) + 1e-12
    lo, hi = lo - pad, hi + pad
    m = np.eye(4)
    m[[0, 1, 2], [0, 1, 2]] = 2 / (hi - lo)
    m[:3, 3] = -(hi + lo) / (hi - lo)
    return m


def _sun_map(view: View, light: Light, region: np.ndarray, box_pts: np.ndarray) -> np.ndarray:
    ell = light.direction
    up = view.direction - (view.direction @ ell) * ell
    if np.linalg.norm(up) < 1e-6:
        up = view.up
    to_light = np.diag([1.0, 1.0, -1.0, 1.0]) @ _look(view.position, ell, up)     # z grows away from the light
    r = region @ to_light[:3, :3].T + to_light[:3, 3]
    b = box_pts @ to_light[:3, :3].T + to_light[:3, 3]
    lo, hi = r.min(axis=0), r.max(axis=0)
    lo[2] = min(lo[2], b[:, 2].min())
    return _window(lo, hi) @ to_light


def _perspective(apex, forward, up, half_x, half_y, near, far) -> np.ndarray:
    v = _look(apex, forward, up)
    p = np.zeros((4, 4))
    p[0, 0], p[1, 1] = 1 / half_x, 1 / half_y
    p[2, 2], p[2, 3] = -(far + near) / (far - near), -2 * far * near / (far - near)
    p[3, 2] = -1
    return p @ v


def _point_maps(view: View, light: Light, region: np.ndarray, scale: float) -> list:
    apex = light.position
    d = region - apex
    dist = np.linalg.norm(d, axis=1)
    near = max(1e-4 * scale, 1e-6)
    far = float(dist.max()) * 1.001 + near
    axis = (d / dist[:, None]).mean(axis=0)
    if np.linalg.norm(axis) > 1e-6:
        axis /= np.linalg.norm(axis)
        up = view.up - (view.up @ axis) * axis
        v = _look(apex, axis, up if np.linalg.norm(up) > 1e-6 else view.direction)
        e = d @ v[:3, :3].T
        ahead = -e[:, 2]
        if np.all(ahead > 1e-9 * scale) and np.max(np.abs(e[:, :2]) / ahead[:, None]) < math.tan(math.radians(60)):
            half_x = float(np.max(np.abs(e[:, 0]) / ahead)) * 1.0001
            half_y = float(np.max(np.abs(e[:, 1]) / ahead)) * 1.0001
            return [_perspective(apex, axis, v[1, :3], half_x, half_y, near, far)]
    faces = []
    for k in range(3):
        for s in (1.0, -1.0):
            f = np.zeros(3)
            f[k] = s
            up = np.eye(3)[2] if k != 2 else np.eye(3)[1]
            faces.append(_perspective(apex, f, up, 1.0, 1.0, near, far))
    return faces


def reference_pssm(view: View, light: Light, scene: SceneBounds, size, count: int = 3, lam: float = 0.5) -> ShadowSetup:
    """The classic PSSM's maps for this configuration (module docs)."""
    size = (size, size) if isinstance(size, int) else tuple(size)
    box = scene.aabb()
    box_pts = box[0] + BOX_CORNERS * (box[1] - box[0])
    depths = view.eye_depth(box_pts)
    near = min(max(view.near, float(depths.min())), view.far * 0.999)
    far = max(min(view.far, float(depths.max())), near * 1.001)
    splits = practical_splits(near, far, count, lam)
    maps = []
    for i in range(count):
        region = clipped_to_box(_split_corners(view, splits[i], splits[i + 1]), box)
        if len(region) == 0:
            continue
        start = view.near if i == 0 else splits[i]
        end = view.far if i == count - 1 else splits[i + 1]
        if light.is_directional:
            matrices = [_sun_map(view, light, region, box_pts)]
        else:
            matrices = _point_maps(view, light, region, float(np.linalg.norm(box[1] - box[0])))
        maps += [ShadowMap(m, size, "LESS", f"pssm{i}", view_depth_range=(start, end)) for m in matrices]
    return ShadowSetup(maps, Diagnostics("reference_pssm"))
