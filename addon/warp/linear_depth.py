"""Linear depth rows (Scherzer §4.2, "linear z-distribution"): z = r · [x, y, z, 1], affine in the world
position, growing along every light ray and spanning [-1, 1] over the map's points (docs/papers.md)."""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from .fit import window_matrix
from .frame import LightFrame, light_cone
from .geometry import homogeneous
from .types import Light

AXIS_MARGIN = math.cos(math.radians(89.0))
"""A point light's depth axis must be within 89° of every ray it measures: nearer to 90° the depth hardly grows along
the ray and its float32 steps are long (``light_depth_row`` gives None then)."""


def fitted_row(along: np.ndarray, points) -> np.ndarray:
    """The depth row ``along`` (an affine function, 4 entries) scaled and offset
    so that ``points`` span [-1, 1] (padded like the unit-cube fit)."""
    d = homogeneous(points) @ along
    window = window_matrix([float(d.min())] * 3, [float(d.max())] * 3)
    return window[2, 2] * along + np.array([0.0, 0.0, 0.0, window[2, 3]])


def frame_depth_row(frame: LightFrame, points=None) -> np.ndarray:
    """The linear depth of a light frame over its points (or ``points``): light-space z, or a perspective's w."""
    along = frame.to_light[2] if frame.directional else frame.to_light[3]
    return fitted_row(along, frame.points if points is None else points)


def light_depth_row(light: Light, body) -> Optional[np.ndarray]:
    """The linear depth of ``light`` over B without a frame: along a sun's direction; for a point or spot light
    outside B, along the most acute axis to B's every ray (docs/papers.md). None when that is 89° or more."""
    points = body.vertices
    if light.is_directional:
        return fitted_row(np.append(light.direction, 0.0), points)
    rays = light.rays_to(points)
    poly = body.polytope
    facing = poly.normals @ (light.position - body.origin) > poly.offsets
    axes = np.array([light_cone(points, light.position)[0], *-poly.normals[facing]])
    acute = (rays @ axes.T).min(axis=0)
    best = int(np.argmax(acute))
    if not acute[best] > AXIS_MARGIN:
        return None
    axis = axes[best]
    return fitted_row(np.append(axis, -float(axis @ light.position)), points)
