"""Stable cascades: maps that keep every world point on its texel while the camera moves.

A shadow edge shimmers when the map's texel grid moves over the scene: each
frame resamples the casters on a shifted or rescaled grid. The classic remedy
(stable cascaded shadow maps) fixes three things for a sun:

* **the grid's orientation**: the light frame is fixed in the world
  (``frame.world_sun_frame``), not turned with the camera;
* **the grid's scale**: each split's window is the square around the bounding
  sphere of the split's slab of the view frustum, whose radius depends on the
  split's depths and the lens only, not on where the camera looks or stands;
* **the grid's phase**: the window's corner is snapped to whole texels.

Then a moving camera shifts each map by whole texels and nothing else. The
splits themselves must stand still too: ``stable_depth_range`` rounds the
depth range's ends outwards to whole octaves (the PSSM splits of that range
change only when the visible range crosses one), and the split warps are all
uniform (a perspective warp moves with the eye).

A spot light's map (``stable_spot_map``) is the spot's own perspective (its
apex, axis and an up fixed in the world): a world point keeps its place on the
image plane while the camera moves. The window around B_i's image grows to a
ladder of sizes (``LADDER_STEPS`` per octave) and its corner snaps to whole
texels of that plane, so it changes scale only when B_i's image crosses a
step. A point light's faces turn with B (``frame.point_frames``) and are not
stabilised.
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
"""A stable spot map's window sides are 2^(k/8): about 9 % apart."""


def stable_depth_range(z_n: float, z_f: float, view: View) -> tuple[float, float]:
    """[z_n, z_f] widened to whole octaves (2^k), within the camera's clip range."""
    near = max(2.0 ** math.floor(math.log2(z_n)), view.near)
    far = min(2.0 ** math.ceil(math.log2(z_f)), view.far)
    return near, max(far, near * (1 + 1e-9))


def slab_sphere(split_view: View) -> tuple[np.ndarray, float]:
    """The bounding sphere of a split's slab of the view frustum (its 8 corners):
    centred on the segment between its near and far faces' centres, where the
    farthest corners of both faces are equally far (an enclosing sphere whatever
    the lens shift; the smallest one for a centred lens)."""
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
                   role: str = "main", linear_z: bool = False) -> ShadowMap:
    """A split's uniform sun map on a texel grid fixed in the world (module docs):
    the window holds the slab's bounding sphere (so B_i's image, which is R_i's
    for a sun), its corner on whole texels t = 2r / (size - 1); its depth holds B_i."""
    frame = world_sun_frame(light, body)
    centre_world, radius = slab_sphere(split_view)
    centre = frame.to_light[:3, :3] @ centre_world + frame.to_light[:3, 3]
    texel = 2.0 * radius / (np.asarray(size, dtype=np.float64) - 1.0)
    lo = np.floor((centre[:2] - radius) / texel) * texel
    hi = lo + texel * np.asarray(size, dtype=np.float64)
    depth = body.vertices @ frame.to_light[2, :3] + frame.to_light[2, 3]
    matrix = window_matrix([*lo, depth.min()], [*hi, depth.max()]) @ frame.to_light
    return ShadowMap(matrix, tuple(size), "LESS", role, depth_row=matrix[2].copy() if linear_z else None)


def stable_spot_map(light: Light, body: IntersectionBody, size: tuple[int, int], max_angle: float,
                    role: str = "main", linear_z: bool = False) -> ShadowMap | None:
    """A split's spot map on an image plane fixed in the world (module docs), or
    None when B_i leaves the spot's frustum of ``max_angle`` around its axis."""
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
    lo, hi = image.min(axis=0), image.max(axis=0)
    side = 2.0 ** (np.ceil(np.log2(np.maximum(hi - lo, 1e-300)) * LADDER_STEPS) / LADDER_STEPS)
    texel = side / (np.asarray(size, dtype=np.float64) - 1.0)
    corner = np.floor(lo / texel) * texel
    h = transform_h(to_light, body.vertices[ahead])
    z = h[:, 2] / h[:, 3]
    matrix = window_matrix([*corner, z.min()], [*(corner + texel * np.asarray(size, dtype=np.float64)), z.max()]) @ to_light
    return ShadowMap(matrix, tuple(size), "LESS", role, depth_row=None)
