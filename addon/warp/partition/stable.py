"""Stable cascades, every world point on its texel while the camera moves (docs/papers.md, ``addon/warp/partition``):
a sun split's window the square about its slab's sphere (Valient, ShaderX6), a spot's on a ladder of windows."""
from __future__ import annotations

import math

import numpy as np

from ..body import IntersectionBody
from ..fit import window_matrix
from ..frame import WORLD_NORTH, WORLD_UP, image_up, near_far, perspective_of, world_sun_frame
from ..geometry import UNIT_CUBE_CORNERS, look_along, transform_points
from ..types import Light, ShadowMap, View

LADDER_STEPS = 8
"""A stable spot window's sides are 2^(k/8), about 9 % apart."""


def stable_depth_range(z_f: float, view: View) -> tuple[float, float]:
    """[near clip, z_f widened to a whole octave (2^k)] within the camera's clip range: the nearest depth seen
    crosses octaves back and forth as the camera moves (and every split with it); the near clip stays."""
    far = min(2.0 ** math.ceil(math.log2(z_f)), view.far)
    return view.near, max(far, view.near * (1 + 1e-9))


def stable_spot_map(light: Light, body: IntersectionBody, size: tuple[int, int], max_angle: float) -> ShadowMap | None:
    """A split's spot map on a world-fixed image plane, or None when B_i leaves ``max_angle`` around the spot's axis."""
    eye = look_along(light.position, light.direction, image_up(WORLD_UP, WORLD_NORTH, light.direction))
    rel = body.vertices @ eye[:3, :3].T + eye[:3, 3]
    depth, floor = -rel[:, 2], 1e-6 * body.scale         # depths along the spot's axis, the least one ahead
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
    z = transform_points(to_light, body.vertices[ahead])[:, 2]
    matrix = window_matrix([*corner, z.min()], [*(corner + texel * n), z.max()]) @ to_light
    return ShadowMap(matrix, tuple(size), "LESS", "main")


def stable_sun_map(light: Light, body: IntersectionBody, split: View, size: tuple[int, int]) -> ShadowMap:
    """A split's map in the world-fixed sun frame: the square about the sphere (centred on the slab's box in eye
    space) around ``split``'s slab, its corner on whole texels; depths B_i's (B_i's own image turns with the camera)."""
    to_light = world_sun_frame(light, body).to_light
    eye = transform_points(np.linalg.inv(split.projection), UNIT_CUBE_CORNERS)
    centre = transform_points(split.camera_to_world, (0.5 * (eye.min(axis=0) + eye.max(axis=0)))[None])[0]
    radius = float(np.sqrt(((split.corners() - centre) ** 2).sum(axis=1).max()))
    n = np.asarray(size, dtype=np.float64)
    texel = 2.0 * radius / (n - 1.0)                     # a texel to spare for the corner's rounding
    corner = np.floor((transform_points(to_light, centre[None])[0, :2] - radius) / texel) * texel
    z = transform_points(to_light, body.vertices)[:, 2]
    return ShadowMap(window_matrix([*corner, z.min()], [*(corner + texel * n), z.max()]) @ to_light,
                     tuple(size), "LESS", "main")
