"""Light frames: the transform after which a light's rays run parallel to +z (z growing away from the
light), x, y spanning the map, +y along V_P (Scherzer §4.4, Eq. 3; Stamminger-Drettakis §3; docs/papers.md)."""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

import numpy as np

from .aliasing import folded
from .body import IntersectionBody
from .polyhedron import SNAP, ConvexPolytope, Edges, section_points
from .geometry import across, cross, depth_coefficients, dot3, homogeneous, look_along, normalize, perpendicular
from .types import Light, View, WarpError, WarpOptions

PARALLEL_BLEND = math.sin(math.radians(1.0))
"""Below this |projected view direction| the camera's up vector takes over."""

FLIP_Z = np.diag([1.0, 1.0, -1.0, 1.0])

NEAR_FLOOR = 1e-6
"""A point light's maps (and plane maps' casters) reach no nearer to it than this fraction of B's scale."""


@dataclass(frozen=True)
class LightFrame:
    """``to_light``: world -> light space (projective for point lights); ``points``: world vertices of the part of B
    it serves; ``role``; ``directional``; ``near_clamped``: reported as a "near plane" fallback."""

    to_light: np.ndarray
    points: np.ndarray
    role: str
    directional: bool
    near_clamped: bool = False

    @cached_property
    def points_h(self) -> np.ndarray:
        """``points`` with w = 1 (N, 4), made once."""
        return homogeneous(self.points)


PARALLEL_TWIST = 2.0
"""Weight of the camera's right vector inside the blend (see ``image_up``)."""


def image_up_blend(view_direction, view_up, light_direction) -> list:
    """``image_up`` before its normalisation, as 3 floats (its length is 0 only at the blend's singular point)."""
    d = normalize(light_direction).tolist()
    v = np.asarray(view_direction, dtype=np.float64).tolist()
    pv = across(v, d)
    s = math.sqrt(dot3(pv, pv))
    if s >= PARALLEL_BLEND:
        return [c / s for c in pv]
    u = np.asarray(view_up, dtype=np.float64).tolist()
    pu = across(u, d)
    pr = across(cross(v, u).tolist(), d)
    nu, nr = math.sqrt(dot3(pu, pu)), math.sqrt(dot3(pr, pr))
    if not nu > 0 or not nr > 0:
        return [c / s for c in pv] if s > 0 else pv
    t = s / PARALLEL_BLEND
    v_p = [c / s for c in pv] if s > 0 else [0.0, 0.0, 0.0]
    twist = PARALLEL_TWIST * t * (1 - t)
    return [t * a + (1 - t) * b / nu + twist * c / nr for a, b, c in zip(v_p, pu, pr)]


def image_up(view_direction, view_up, light_direction) -> np.ndarray:
    """The map's +y: V_P = (V_light x V_eye) x V_light (Scherzer Eq. 3) across the light, blended within
    PARALLEL_BLEND of parallel into the camera's up (``image_up_blend``)."""
    up = image_up_blend(view_direction, view_up, light_direction)
    length = math.sqrt(dot3(up, up))
    return np.zeros(3) if length < 1e-300 else np.array([c / length for c in up])


def up_across(view: View, axis) -> np.ndarray:
    """The map's +y across a light ``axis`` (``image_up`` of the view), or a perpendicular at its singular point."""
    up = image_up(view.direction, view.up, axis)
    return up if up.any() else perpendicular(axis)


def light_angles(view: View, light_direction) -> tuple[float, float]:
    """(θ, γ): γ the angle between view and light directions (Scherzer §4.4), θ folded (GMNPR)."""
    c = min(max(dot3(view.direction.tolist(), normalize(light_direction).tolist()), -1.0), 1.0)
    gamma = math.acos(c)
    return folded(gamma), gamma


def body_light_angles(view: View, light: Light, body: IntersectionBody) -> tuple[float, float]:
    """``light_angles`` to a sun's direction, or from a point or spot light to B's centroid."""
    return light_angles(view, light.direction if light.is_directional else body.centroid - light.position)


def sun_frame(view: View, light: Light, body: IntersectionBody) -> LightFrame:
    """Orthographic frame of a sun, anchored at the camera for precision."""
    return _sun_frame(light, body, view.position, image_up(view.direction, view.up, light.direction))


def _sun_frame(light: Light, body: IntersectionBody, eye, up) -> LightFrame:
    """A sun's orthographic frame looking along its light from ``eye``, +y ``up``."""
    return LightFrame(FLIP_Z @ look_along(eye, light.direction, up), body.vertices, "main", True)


SURROUND_BLEND = 0.2
"""Below this length of the direction-box centre (B nearly surrounds the light)
the cone axis blends continuously towards ``SURROUND_AXIS``."""
SURROUND_AXIS = np.array([0.0, 0.0, -1.0])
"""The cube axis for a light surrounded by B: world down (Blender is Z-up)."""


WORLD_UP = np.array([0.0, 0.0, 1.0])
WORLD_NORTH = np.array([0.0, 1.0, 0.0])


def world_sun_frame(light: Light, body: IntersectionBody) -> LightFrame:
    """An orthographic sun frame fixed in the world (+y: world up across the light,
    blended as in ``image_up``), so a texel-snapped window keeps its grid as the camera moves."""
    return _sun_frame(light, body, np.zeros(3), image_up(WORLD_UP, WORLD_NORTH, light.direction))


def light_cone(points: np.ndarray, apex: np.ndarray) -> tuple[np.ndarray, float]:
    """Axis and half-angle of a cone from ``apex`` holding B's ``points`` (apex ones ignored; near π: no single cone)."""
    dirs = np.asarray(points, dtype=np.float64) - apex
    norms = np.sqrt(np.einsum("ij,ij->i", dirs, dirs))
    # Points at the apex itself (B has the light as a vertex when the light is
    # outside R) have no direction: a rounding error would give them any.
    far = norms > 1e-7 * float(norms.max())
    dirs = dirs[far] / norms[far, None]
    mid = [(a + b) / 2 for a, b in zip(dirs.min(axis=0).tolist(), dirs.max(axis=0).tolist())]   # (plain floats)
    short = SURROUND_BLEND - math.hypot(*mid)
    if short > 0:
        mid = [m + short * s for m, s in zip(mid, SURROUND_AXIS.tolist())]
    length = math.hypot(*mid)
    if length < 1e-12:
        mid, length = SURROUND_AXIS.tolist(), 1.0
    axis = np.array([m / length for m in mid])
    return axis, math.acos(min(max(float((dirs @ axis).min()), -1.0), 1.0))


def perspective_frame(apex, axis, up_hint, points, role, scale, floor: float | None = None,
                      cuts_a_box: bool = True) -> LightFrame:
    """A point light's perspective along ``axis`` from ``apex`` (rays become parallel to z), near at the nearest
    point's depth clamped to ``floor`` (``NEAR_FLOOR`` x ``scale``); ``cuts_a_box``: whether that clamp matters."""
    view = look_along(apex, axis, up_hint)
    depth = (points - apex) @ -view[2, :3]                   # along the axis (the eye looks down -z)
    floor = NEAR_FLOOR * scale if floor is None else floor
    near, far, clamped = near_far(float(depth.min()), float(depth.max()), floor)
    if clamped:         # B from the floor on, and where the light's rays to it cross the floor (to all of B if none)
        ahead = depth >= floor
        rays = ahead if ahead.any() else depth > 0
        points = np.concatenate([points[ahead], apex + (points[rays] - apex) * (floor / depth[rays])[:, None]])
    return LightFrame(perspective_of(view, near, far), points, role, False, clamped and cuts_a_box)


CUBE_FACE_COS = 1.0 / math.sqrt(3.0)
"""cos of the widest angle between a cube face's axis and a ray of its pyramid (its corner rays)."""


def nearest_box_distance(body: IntersectionBody, apex) -> float:
    """The distance from ``apex`` to the nearest caster or receiver box B was built
    from (inf: none): nothing nearer can cast or receive a shadow."""
    apex = np.asarray(apex, dtype=np.float64)
    gaps = [np.maximum(np.maximum(b[:, 0] - apex, apex - b[:, 1]), 0.0)
            for b in [s.boxes for s in (body.culled.casters, body.culled.receivers) if s.box is not None]]
    return min([float(np.sqrt(np.einsum("ij,ij->i", g, g)).min()) for g in gaps], default=math.inf)


def cube_near_floor(body: IntersectionBody, apex, hyperbolic: bool,
                    widest_cos: float = CUBE_FACE_COS) -> tuple[float, bool]:
    """The near distance of a point light's cube faces with the light on or in B, and whether it cuts a box that
    matters: ``NEAR_FLOOR`` of B's scale for linear depth (Scherzer §4.2), else the nearest box's distance times
    ``widest_cos``."""
    least = NEAR_FLOOR * body.scale
    bound = 0.999 * widest_cos * nearest_box_distance(body, apex)
    return (max(bound, least) if hyperbolic and math.isfinite(bound) else least), bound < least


def near_far(nearest: float, farthest: float, floor: float) -> tuple[float, float, bool]:
    """(near, far, clamped) of a perspective frame: near clamped to ``floor``, far a little beyond near."""
    near = max(nearest, floor)
    return near, max(farthest, near * (1 + 1e-9) + floor), nearest < floor


def perspective_of(view: np.ndarray, near: float, far: float) -> np.ndarray:
    """``proj @ view`` for the unit-image-plane OpenGL perspective, row by row."""
    a, b = depth_coefficients(near, far)
    m = view.copy()
    m[2] = a * view[2]
    m[2, 3] += b
    m[3] = -view[2]
    return m


CUBE_FACES = (("+X", 0, 1.0), ("-X", 0, -1.0), ("+Y", 1, 1.0), ("-Y", 1, -1.0), ("+Z", 2, 1.0), ("-Z", 2, -1.0))

_FACE_ROWS = np.array([[2, 1, 0], [2, 1, 0], [0, 2, 1], [0, 2, 1], [0, 1, 2], [0, 1, 2]])
_FACE_ROW_SIGNS = np.array([[1.0, 1.0, -1.0], [-1.0, 1.0, 1.0], [1.0, 1.0, -1.0],
                            [-1.0, 1.0, 1.0], [-1.0, 1.0, -1.0], [1.0, 1.0, 1.0]])
"""Each cube face's eye rotation (``look_along`` rows x, y, -forward) as signed rows of the cube's basis."""
_FACE_TURNS = np.where(np.eye(3)[_FACE_ROWS] > 0, _FACE_ROW_SIGNS[..., None], 0.0)
"""The same as signed permutations (6, 3, 3): face f's eye rotation is ``_FACE_TURNS[f] @ basis``."""


def point_frames(view: View, light: Light, body: IntersectionBody, options: WarpOptions) -> list[LightFrame]:
    """One perspective frame when B fits a frustum narrower than ``max_frustum_angle``, else one per cube face B
    reaches, the cube aligned with the cone axis or ``body.cube_axis`` (a known discontinuity in the number of maps)."""
    apex = light.position
    axis, half = light_cone(body.vertices, apex)
    up = up_across(view, axis)
    inside = body.contains(apex[None], -10.0 * body.tolerance)[0]                  # (strictly inside B)
    if 2 * half <= options.max_frustum_angle and not inside:
        floor, cuts_a_box = cube_near_floor(body, apex, not options.linear_z, math.cos(half)) \
            if body.contains(apex[None])[0] else (None, True)                         # (on B, or outside it)
        return [perspective_frame(apex, axis, up, body.vertices, "main", body.scale, floor, cuts_a_box)]
    axis = axis if body.cube_axis is None else body.cube_axis
    basis = cube_basis(axis, up_across(view, axis))
    near_floor, cuts_a_box = cube_near_floor(body, apex, not options.linear_z)
    turns = _FACE_TURNS @ basis                              # (6, 3, 3): each face's eye rows x, y, -forward
    views = np.tile(np.eye(4), (6, 1, 1))                    # each face's view: those rows through the apex
    views[:, :3, :3], views[:, :3, 3] = turns, -(turns @ apex)
    frames = []
    for f, part, nearest, farthest in cube_sections(body.polytope_from(apex), basis):
        clamped = nearest < near_floor
        if clamped:
            # B reaches nearer than the near floor in this face: from the floor on, the whole face when B
            # surrounds the light, else where the segments from the light to B's other points cross it.
            forward = -turns[f, 2]
            depth = part @ forward
            ahead = depth >= near_floor
            part = np.concatenate([part[ahead], near_floor * (_FACE_RAYS[f] @ basis) if inside or not ahead.any()
                                   else part[ahead] * (near_floor / depth[ahead])[:, None]])
            farthest = float((part @ forward).max())
        to_light = perspective_of(views[f], *near_far(nearest, farthest, near_floor)[:2])
        frames.append(LightFrame(to_light, part + apex, "cube" + CUBE_FACES[f][0], False, clamped and cuts_a_box))
    if not frames:         # (a guard: B is at least 1000 tolerances thick, its scale what the view sees, test_limits)
        raise WarpError(f"Light '{light.name}': no cube face holds a part of B (what is seen and what can shadow it) "
                        f"thicker than its tolerance: check its and the camera's transforms")
    return frames


def cube_basis(axis, up) -> np.ndarray:
    """The cube's axes (rows) for a unit cone ``axis`` and image ``up``: x = up × -axis,
    y = up across the axis, z = -axis (the -Z face looks along the axis)."""
    a, u = np.asarray(axis, dtype=np.float64), np.asarray(up, dtype=np.float64)
    return np.array([normalize(cross(a, u)), normalize(u - (u @ a) * a), -a])


_FACE_CORNERS = np.array([[-1.0, -1.0], [-1.0, 1.0], [1.0, -1.0], [1.0, 1.0]])
_FACE_RAYS = _FACE_CORNERS @ _FACE_TURNS[:, :2] - _FACE_TURNS[:, 2:]
"""Each cube face's 4 corner rays forward + a·x + b·y (a, b = ±1; x, y: its eye rows), cube basis, (6, 4, 3)."""
_FACE_SIDES = (_FACE_TURNS[:, [0, 0, 1, 1]] * [[1.0], [-1.0], [1.0], [-1.0]] + _FACE_TURNS[:, 2:]) / math.sqrt(2)
"""Each face's pyramid's 4 sides' unit outward normals (±x - forward)/√2, (±y - forward)/√2, cube basis."""
_FACE_SIDES_AND_AXES = np.concatenate([_FACE_SIDES.reshape(24, 3), -_FACE_TURNS[:, 2]])
"""The faces' sides, then their axes (forward), in the cube's basis."""


def pyramid_sections(poly: ConvexPolytope, sides: np.ndarray, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points whose hull is P ∩ C_j for k pyramids with apex at the origin (``sides``,
    ``rays`` (k, 4, 3)), by ``polyhedron.section_points``: the points and their pyramid."""
    return section_points(poly, sides, np.zeros(sides.shape[:2]),
                          Edges(np.zeros_like(rays), rays, np.full(rays.shape[:2], np.inf)))


class FacePart(NamedTuple):
    """A cube face's part of P (``cube_sections``): the ``face``'s number in CUBE_FACES, ``points`` whose convex hull
    is P ∩ C_face (relative to the apex), and the ``nearest`` and ``farthest`` of their depths along the face's axis."""

    face: int
    points: np.ndarray
    nearest: float
    farthest: float


def cube_sections(poly: ConvexPolytope, basis: np.ndarray) -> list[FacePart]:
    """The parts of P (relative to the apex) with volume in the faces of the cube with axes ``basis``."""
    planes = _FACE_SIDES_AND_AXES @ basis                    # (30, 3): the 6 x 4 sides, then the 6 axes
    pts, face = pyramid_sections(poly, planes[:24].reshape(6, 4, 3), _FACE_RAYS @ basis)
    counts = np.bincount(face, minlength=6).tolist()
    faces = [f for f in range(6) if counts[f]]
    ends = list(itertools.accumulate(counts[f] for f in faces))
    starts = [e - counts[f] for f, e in zip(faces, ends)]
    distance = pts @ planes.T                                # to each side (outwards) and along each axis
    least = np.minimum.reduceat(distance, starts).tolist()
    most = np.maximum.reduceat(distance[:, 24:], starts).tolist()
    return [FacePart(f, pts[s:e], lo[24 + f], hi[f]) for f, s, e, lo, hi in zip(faces, starts, ends, least, most)
            if e - s >= 4 and max(lo[4 * f: 4 * f + 4]) < -SNAP * poly.tol]


def light_frames(view: View, light: Light, body: IntersectionBody, options: WarpOptions) -> list[LightFrame]:
    """The frames a light needs for this body, in selection order."""
    return [sun_frame(view, light, body)] if light.is_directional else point_frames(view, light, body, options)
