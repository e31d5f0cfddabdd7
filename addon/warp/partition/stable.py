"""Stable cascades: every world point keeps its texel while the camera moves.
A sun split's grid (stable CSM) has a world-fixed orientation, a scale from its
depths and lens only (its slab's bounding sphere) and its corner on whole texels;
the range widens to whole octaves and every warp is uniform. A spot split is the
spot's own perspective, its window on a ladder of sizes, its corner on whole
texels. A point light's faces turn with B: not stable.
"""
from __future__ import annotations

import math

import numpy as np

from ..body import IntersectionBody
from ..fit import window_matrix
from ..frame import WORLD_NORTH, WORLD_UP, image_up, near_far, perspective_of, world_sun_frame
from ..geometry import look_along, transform_h
from ..types import Light, ShadowMap, View

LADDER_STEPS = 8
"""A stable spot window's sides are 2^(k/8), about 9 % apart."""


def stable_depth_range(z_n: float, z_f: float, view: View) -> tuple[float, float]:
    """[z_n, z_f] widened to whole octaves (2^k), within the camera's clip range."""
    near = max(2.0 ** math.floor(math.log2(z_n)), view.near)
    far = min(2.0 ** math.ceil(math.log2(z_f)), view.far)
    return near, max(far, near * (1 + 1e-9))


def slab_sphere(split_view: View) -> tuple[np.ndarray, float]:
    """A sphere around the slab's 8 corners, centred between its faces' centres
    where both faces' farthest corners are equally far (least for a centred lens)."""
    corners = split_view.corners()
    near_c, far_c = corners[:4].mean(axis=0), corners[4:].mean(axis=0)
    r_near = float(np.linalg.norm(corners[:4] - near_c, axis=1).max())
    r_far = float(np.linalg.norm(corners[4:] - far_c, axis=1).max())
    axis = far_c - near_c
    length2 = float(axis @ axis)
    t = min(max((length2 + r_far ** 2 - r_near ** 2) / (2.0 * length2), 0.0), 1.0) if length2 > 0 else 0.0
    centre = near_c + t * axis
    return centre, float(np.linalg.norm(corners - centre, axis=1).max())


def stable_sun_map(split_view: View, light: Light, body: IntersectionBody, size: tuple[int, int],
                   linear_z: bool = False) -> ShadowMap:
    """A split's uniform sun map on a world-fixed grid: the window holds the slab's
    sphere (so B_i's image), corner on whole texels t = 2r / (size - 1); depth holds B_i."""
    frame = world_sun_frame(light, body)
    centre_world, radius = slab_sphere(split_view)
    centre = frame.to_light[:3, :3] @ centre_world + frame.to_light[:3, 3]
    n = np.asarray(size, dtype=np.float64)
    texel = 2.0 * radius / (n - 1.0)
    lo = np.floor((centre[:2] - radius) / texel) * texel
    depth = body.vertices @ frame.to_light[2, :3] + frame.to_light[2, 3]
    matrix = window_matrix([*lo, depth.min()], [*(lo + texel * n), depth.max()]) @ frame.to_light
    return ShadowMap(matrix, tuple(size), "LESS", "main", depth_row=matrix[2].copy() if linear_z else None)


def stable_spot_map(light: Light, body: IntersectionBody, size: tuple[int, int], max_angle: float) -> ShadowMap | None:
    """A split's spot map on a world-fixed image plane, or None when B_i leaves
    ``max_angle`` around the spot's axis."""
    eye = look_along(light.position, light.direction, image_up(WORLD_UP, WORLD_NORTH, light.direction))
    rel = body.vertices @ eye[:3, :3].T + eye[:3, 3]
    depth = -rel[:, 2]                                   # along the spot's axis
    floor = 1e-6 * body.scale
    ahead = depth > floor
    image = rel[ahead, :2] / depth[ahead, None]          # on the plane one unit ahead of the light
    if not ahead.any() or np.abs(image).max() > math.tan(max_angle / 2):
        return None
    near, far, _ = near_far(float(depth[ahead].min()), float(depth.max()), floor)
    to_light = perspective_of(eye, near, far)
    lo, n = image.min(axis=0), np.asarray(size, dtype=np.float64)
    side = 2.0 ** (np.ceil(np.log2(np.maximum(image.max(axis=0) - lo, 1e-300)) * LADDER_STEPS) / LADDER_STEPS)
    texel = side / (n - 1.0)
    corner = np.floor(lo / texel) * texel
    h = transform_h(to_light, body.vertices[ahead])
    z = h[:, 2] / h[:, 3]
    matrix = window_matrix([*corner, z.min()], [*(corner + texel * n), z.max()]) @ to_light
    return ShadowMap(matrix, tuple(size), "LESS", "main")
