"""Light frames: the transform after which a light's rays are parallel.

Every method works in a *light space* in which light rays run parallel to +z
(z grows away from the light) and x, y span the shadow-map image. For a sun the
frame is a rotation (orthographic light); for a point or spot light it is the
light's perspective (Stamminger-Drettakis §3: after it the light is
directional). A point light whose needs do not fit one frustum narrower than
``WarpOptions.max_frustum_angle`` gets one frame per cube face that B needs.

The image's +y axis is the view direction projected onto the image plane (the
LiSPSM V_P of Scherzer §4.4, Eq. 3), blended continuously with the camera's up
vector when light and view are (nearly) parallel, so the frame never jumps.
"""
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
from .geometry import across, cross, dot3, homogeneous, look_along, normalize, perpendicular
from .types import Light, View, WarpOptions

PARALLEL_BLEND = math.sin(math.radians(1.0))
"""Below this |projected view direction| the camera's up vector takes over."""

FLIP_Z = np.diag([1.0, 1.0, -1.0, 1.0])


@dataclass(frozen=True)
class LightFrame:
    """``to_light``: world -> light space (projective for point lights);
    ``points``: world-space vertices of the part of B this frame serves;
    ``role``: "main" or "cube+X" etc.; ``directional``: orthographic frame;
    ``near_clamped``: the near plane cuts off part of a box that matters
    (``cube_near_floor``): what lies nearer is not covered (methods report it
    as a "near plane" fallback); the part of B nearer than the near plane that
    holds no box is left out without a word, since nothing there casts or
    receives a shadow."""

    to_light: np.ndarray
    points: np.ndarray
    role: str
    directional: bool
    near_clamped: bool = False

    @cached_property
    def points_h(self) -> np.ndarray:
        """``points`` with w = 1 (N, 4), made once for the several fits of one setup."""
        return homogeneous(self.points)


PARALLEL_TWIST = 2.0
"""Weight of the camera's right vector inside the blend (see ``image_up``)."""


def _image_up_raw(view_direction, view_up, light_direction) -> list:
    """``image_up`` before its normalisation, as 3 floats."""
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
    """The map's +y: the view direction projected perpendicular to the light
    (Scherzer Eq. 3, V_P = (V_light x V_eye) x V_light up to sign), blended
    into the projected camera up when light and view are within
    PARALLEL_BLEND (sin 1°) of parallel:

        up = t V_P + (1 - t) up_cam + 2 t (1 - t) right_cam,   t = |V_P| / sin 1°

    (all projected across the light). At exact parallel it is the camera's up
    (a top-down camera under a zenith sun gets a map aligned with its image);
    at t = 1 it is V_P. Around the light direction V_P turns once, so any
    continuous choice must turn the map by 180° somewhere inside the blend and
    has a singular point: the right-vector term puts it at t ≈ 0.61 in a
    diagonal direction (about 140° from the camera's up), off the paths of a
    plain pitch or pan through the light direction, which turn the map smoothly
    instead (``image_up_singularity`` measures the distance to it)."""
    up = _image_up_raw(view_direction, view_up, light_direction)
    length = math.sqrt(dot3(up, up))
    if length < 1e-300:
        return np.zeros(3)
    return np.array([c / length for c in up])


def image_up_singularity(view_direction, view_up, light_direction) -> float:
    """How far ``image_up`` is from its singular point: the length of the
    unnormalised blend (about 0.5 or more on plain pitch or pan paths and 1
    outside the blend, 0 at the point). Within a distance ε of it a rotation by
    δ turns the map by about δ / (ε sin 1°)."""
    up = _image_up_raw(view_direction, view_up, light_direction)
    return math.sqrt(dot3(up, up))


def light_angles(view: View, light_direction) -> tuple[float, float]:
    """(θ, γ): γ = angle between view and light directions in [0, π]
    (LiSPSM's γ, Scherzer §4.4); θ in [0, π/2] folded by symmetry (GMNPR)."""
    c = min(max(dot3(view.direction.tolist(), normalize(light_direction).tolist()), -1.0), 1.0)
    gamma = math.acos(c)
    return folded(gamma), gamma


def body_light_angles(view: View, light: Light, body: IntersectionBody) -> tuple[float, float]:
    """``light_angles`` to the light's axis towards B: a sun's direction, or
    from a point or spot light to B's centroid (what a map's θ and γ report
    when no warp has its own)."""
    return light_angles(view, light.direction if light.is_directional else body.centroid - light.position)


def sun_frame(view: View, light: Light, body: IntersectionBody) -> LightFrame:
    """Orthographic frame of a sun, anchored at the camera for precision."""
    up = image_up(view.direction, view.up, light.direction)
    m = FLIP_Z @ look_along(view.position, light.direction, up)
    return LightFrame(m, body.vertices, "main", True)


SURROUND_BLEND = 0.2
"""Below this length of the direction-box centre (B nearly surrounds the light)
the cone axis blends continuously towards ``SURROUND_AXIS``."""
SURROUND_AXIS = np.array([0.0, 0.0, -1.0])
"""The cube axis for a light surrounded by B: world down (Blender is Z-up)."""


WORLD_UP = np.array([0.0, 0.0, 1.0])
WORLD_NORTH = np.array([0.0, 1.0, 0.0])


def world_sun_frame(light: Light, body: IntersectionBody) -> LightFrame:
    """An orthographic sun frame fixed in the world: origin at the world origin
    and the image's +y along world up projected across the light (world +Y when
    the sun is at the zenith, blended as in ``image_up``). It does not move with
    the camera, so a window snapped to whole texels in it stays on the same
    texel grid while the camera moves (texel snapping; a camera-anchored frame
    would drag the grid along and the edges would crawl)."""
    up = image_up(WORLD_UP, WORLD_NORTH, light.direction)
    m = FLIP_Z @ look_along(np.zeros(3), light.direction, up)
    return LightFrame(m, body.vertices, "main", True)


def light_cone(points: np.ndarray, apex: np.ndarray) -> tuple[np.ndarray, float]:
    """Axis and half-angle of a cone from ``apex`` containing ``points``.

    The axis points at the centre c of the bounding box of the unit directions
    to the points: unlike a mean over vertices it does not jump when a vertex
    of B splits in two, so the light frame moves continuously with the view.
    When B nearly surrounds the light, c is short and its direction
    meaningless, so the axis blends continuously into world down:
    axis = c + max(0, SURROUND_BLEND - |c|) * down (singular only where c points
    up with length SURROUND_BLEND / 2). A half-angle near π means no single
    cone holds the points. Points within 1e-7 of the farthest distance from
    the apex are ignored (a perspective map cannot hold its own centre)."""
    dirs = np.asarray(points, dtype=np.float64) - apex
    norms = np.sqrt(np.einsum("ij,ij->i", dirs, dirs))
    lengths = norms.tolist()
    farthest = max(lengths, default=0.0)
    if farthest == 0:
        return SURROUND_AXIS.copy(), math.pi
    # Points at the apex itself (B has the light as a vertex when the light is
    # outside R) have no direction: a rounding error would give them any.
    if min(lengths) > 1e-7 * farthest:
        dirs /= norms[:, None]
    else:
        far = norms > 1e-7 * farthest
        dirs = dirs[far] / norms[far, None]
    mid = [(a + b) / 2 for a, b in zip(dirs.min(axis=0).tolist(), dirs.max(axis=0).tolist())]   # (plain floats)
    short = SURROUND_BLEND - math.hypot(*mid)
    if short > 0:
        mid = [m + short * s for m, s in zip(mid, SURROUND_AXIS.tolist())]
    length = math.hypot(*mid)
    if length < 1e-12:
        mid, length = SURROUND_AXIS.tolist(), 1.0
    axis = np.array([m / length for m in mid])
    half = math.acos(min(max(float((dirs @ axis).min()), -1.0), 1.0))
    return axis, half


def perspective_frame(apex, axis, up_hint, points, role, scale, floor: float | None = None,
                      cuts_a_box: bool = True) -> LightFrame:
    """A point light's perspective looking along ``axis`` from ``apex``:
    eye space -> (x, y, z_gl, -z) so rays from the apex become parallel to z.
    The near plane is the nearest point's depth, clamped to a scale-relative
    minimum when the light sits on or in the body. Then the points nearer than
    that minimum (the light itself, a vertex of hull(R ∪ light)) give way to
    where the segments from the light to the others cross the near plane:
    every map fitted to the frame's points holds the body from there on.
    ``floor``: that minimum (default 1e-6 of ``scale``; ``near_floor``);
    ``cuts_a_box``: whether what lies nearer matters (the "near plane" note)."""
    view = look_along(apex, axis, up_hint)
    depth = (points - apex) @ -view[2, :3]                   # along the axis (the eye looks down -z)
    floor = 1e-6 * scale if floor is None else floor
    near, far, clamped = near_far(float(depth.min()), float(depth.max()), floor)
    ahead = depth >= floor
    if clamped and ahead.any():
        points = np.concatenate([points[ahead], apex + (points[ahead] - apex) * (floor / depth[ahead])[:, None]])
    return LightFrame(perspective_of(view, near, far), points, role, False, clamped and cuts_a_box)


CUBE_FACE_COS = 1.0 / math.sqrt(3.0)
"""cos of the widest angle between a cube face's axis and a ray of its pyramid (its corner rays)."""


def nearest_box_distance(body: IntersectionBody, apex) -> float:
    """The distance from ``apex`` (a point light) to the nearest box that
    matters: the casters that can shadow what is seen and the receivers in
    view (B's culling). Nothing nearer to the light than this can cast or
    receive a shadow; inf when there is no such box."""
    apex = np.asarray(apex, dtype=np.float64)
    nearest = math.inf
    for selection in (body.culled.casters, body.culled.receivers):
        if selection.box is None:
            continue
        bounds = selection.index.c_box_bounds.reshape(6, -1).compress(selection.by_cluster.ravel(), axis=1)
        lo, hi = bounds[:3].T, -bounds[3:].T                   # (n, 3) each
        gap = np.maximum(np.maximum(lo - apex, apex - hi), 0.0)
        nearest = min(nearest, float(np.sqrt(np.einsum("ij,ij->i", gap, gap)).min()))
    return nearest


def cube_near_floor(body: IntersectionBody, apex, hyperbolic: bool,
                    widest_cos: float = CUBE_FACE_COS) -> tuple[float, bool]:
    """The near distance of a point light's cube faces when the light is inside
    (or on) B, and whether it cuts into a box that matters (then what lies
    nearer is not covered: the "near plane" fallback). ``widest_cos``: cos of
    the widest angle between a face's axis and its rays (one frame's: its cone's).

    With linear depth (the default, Scherzer §4.2) the near plane does not
    touch the depth's precision, so it stays at the least distance a
    perspective map can have, 1e-6 of the scene scale, and B is covered up to
    there. With hyperbolic depth (``linear_z=False``) a near plane that close
    leaves float32 no precision at the receivers (1e-6 of a 340 m scene: depth
    steps of decimetres at 30 m), so it goes to the nearest box that matters:
    every such box is at least ``nearest_box_distance`` from the light, so
    along a face's axis at least that times ``widest_cos``, and only the
    empty part of B nearer than that is left out. (Boxes are bounding boxes: a
    light inside a room's box gains nothing.)"""
    least = 1e-6 * body.scale
    bound = 0.999 * widest_cos * nearest_box_distance(body, apex)
    cuts_a_box = bound < least
    if hyperbolic and math.isfinite(bound):
        return max(bound, least), cuts_a_box
    return least, cuts_a_box


def near_far(nearest: float, farthest: float, floor: float) -> tuple[float, float, bool]:
    """A perspective frame's (near, far, clamped) from its points' depth range:
    near is the nearest depth, clamped to ``floor`` (the light inside B), and
    far stays a little beyond near so the depth range never collapses."""
    near = max(nearest, floor)
    return near, max(farthest, near * (1 + 1e-9) + floor), nearest < floor


def depth_coefficients(near: float, far: float) -> tuple[float, float]:
    """(A, B) of the OpenGL perspective's depth: z_gl = A z + B and w = -z, with
    A = -(f + n)/(f - n), B = -2fn/(f - n) (unit image plane)."""
    return -(far + near) / (far - near), -2 * far * near / (far - near)


def perspective_of(view: np.ndarray, near: float, far: float) -> np.ndarray:
    """``proj @ view`` for the OpenGL perspective with the given near and far
    (unit image plane), written out row by row: x, y pass through, z_gl =
    A z + B and w = -z (``depth_coefficients``)."""
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
"""Each cube face's eye rotation as signed rows of the cube's (right-handed,
orthonormal) basis: ``look_along(apex, forward, face_up)`` with forward =
sign·basis[k] and face_up = basis[1] (basis[2] for the ±Y faces) has rows
x = forward × face_up, y = x × forward and -forward; e.g. +X: (b2, b1, -b0)."""
_FACE_TURNS = np.array([[[sign if j == row else 0.0 for j in range(3)] for row, sign in zip(rows, signs)]
                        for rows, signs in zip(_FACE_ROWS, _FACE_ROW_SIGNS)])
"""The same as signed permutations (6, 3, 3): face f's eye rotation is ``_FACE_TURNS[f] @ basis``."""


def point_frames(view: View, light: Light, body: IntersectionBody, options: WarpOptions) -> list[LightFrame]:
    """One perspective frame when B fits a frustum narrower than
    ``max_frustum_angle``, else one per cube face that B reaches (cube aligned
    with the cone axis to B, so as few faces as possible are needed).

    A light on B's boundary takes the one frame too: B = hull(R ∪ light) ∩ S_c
    has the light as a vertex whenever S_c holds it (a lamp among the boxes, a
    headlamp, each split of a cascade), and then lies in the cone of its other
    points' directions; only a light strictly inside B needs whole cube faces.

    The switch between the two is a known discontinuity (the number of maps
    changes), at ``2 * light_cone(B)[1] == max_frustum_angle``."""
    apex = light.position
    axis, half = light_cone(body.vertices, apex)
    up = image_up(view.direction, view.up, axis)
    if not up.any():
        up = perpendicular(axis)
    inside = body.contains(apex[None], -10.0 * body.tolerance)[0]                  # (strictly inside B)
    if 2 * half <= options.max_frustum_angle and not inside:
        floor, cuts_a_box = None, True
        if body.contains(apex[None])[0]:                                              # (on B)
            floor, cuts_a_box = cube_near_floor(body, apex, not options.linear_z, math.cos(half))
        return [perspective_frame(apex, axis, up, body.vertices, "main", body.scale, floor, cuts_a_box)]
    basis = cube_basis(axis.tolist(), up.tolist())
    near_floor, cuts_a_box = cube_near_floor(body, apex, not options.linear_z)
    turns = _FACE_TURNS @ basis                              # (6, 3, 3): each face's eye rows x, y, -forward
    rows, shifts = turns.tolist(), (-(turns @ apex)).tolist()   # each face's view: rotation rows, translation
    frames, entries = [], []
    for f, part, nearest, farthest in cube_sections(body.polytope_from(apex), basis):
        clamped = nearest < near_floor
        if clamped:
            # B reaches nearer than the near floor in this face: from the floor on, the whole face when B
            # surrounds the light, else where the segments from the light to B's other points cross it.
            forward = -turns[f, 2]
            depth = part @ forward
            ahead = depth >= near_floor
            if inside or not ahead.any():
                others = np.delete(basis, CUBE_FACES[f][1], axis=0)
                nearest_part = near_floor * (forward + _FACE_CORNERS @ others)
            else:
                nearest_part = part[ahead] * (near_floor / depth[ahead])[:, None]
            part = np.concatenate([part[ahead], nearest_part])
            farthest = float((part @ forward).max())
        # The face's view (rows x, y, -forward through the apex) and perspective, entry by entry.
        near, far, _ = near_far(nearest, farthest, near_floor)
        a, b = depth_coefficients(near, far)
        (x, y, (z0, z1, z2)), (tx, ty, tz) = rows[f], shifts[f]
        entries += x + [tx] + y + [ty] + [a * z0, a * z1, a * z2, a * tz + b, -z0, -z1, -z2, -tz]
        frames.append((f, part + apex, clamped and cuts_a_box))
    to_light = np.array(entries).reshape(-1, 4, 4)
    return [LightFrame(m, p, "cube" + CUBE_FACES[f][0], False, c) for m, (f, p, c) in zip(to_light, frames)]


def cube_basis(axis, up) -> np.ndarray:
    """The cube's axes (rows) for a unit cone ``axis`` and an image ``up``
    across it (floats): x = up × -axis, y = up made perpendicular to the axis,
    z = -axis (so the -Z face looks along the axis)."""
    (ax, ay, az), (ux, uy, uz) = axis, up
    x = (ay * uz - az * uy, az * ux - ax * uz, ax * uy - ay * ux)
    k = ux * ax + uy * ay + uz * az
    y = (ux - k * ax, uy - k * ay, uz - k * az)
    nx, ny = math.sqrt(x[0] ** 2 + x[1] ** 2 + x[2] ** 2), math.sqrt(y[0] ** 2 + y[1] ** 2 + y[2] ** 2)
    return np.array([[c / nx for c in x], [c / ny for c in y], [-ax, -ay, -az]])


_FACE_CORNERS = np.array([[-1.0, -1.0], [-1.0, 1.0], [1.0, -1.0], [1.0, 1.0]])
"""(a, b) of a cube face's 4 corner rays forward + a·others[0] + b·others[1]."""


def _face_pyramids() -> tuple[np.ndarray, np.ndarray]:
    """Each cube face's pyramid in the cube's basis, C_f = {|o · x| <= forward ·
    x for both other axes o}: its 4 sides' unit outward normals (s·o - forward)
    / √2 and its 4 corner rays forward + a·o_1 + b·o_2, (6, 4, 3) each."""
    sides, rays = [], []
    for _, k, sign in CUBE_FACES:
        forward, (o1, o2) = sign * np.eye(3)[k], np.delete(np.eye(3), k, axis=0)
        sides.append([(s * o - forward) / math.sqrt(2.0) for o in (o1, o2) for s in (1.0, -1.0)])
        rays.append([forward + a * o1 + b * o2 for a, b in _FACE_CORNERS])
    return np.array(sides), np.array(rays)


_FACE_SIDES, _FACE_RAYS = _face_pyramids()
_FACE_SIDES_AND_AXES = np.concatenate([_FACE_SIDES.reshape(24, 3), -_FACE_TURNS[:, 2]])
"""The faces' sides, then their axes (forward), in the cube's basis."""


def pyramid_sections(poly: ConvexPolytope, sides: np.ndarray, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points whose convex hull is P ∩ C_j for k pyramids C_j with their apex at
    the origin (P relative to the apex, e.g. a point light), all at once:
    ``sides`` (k, 4, 3) their sides' unit outward normals, ``rays`` (k, 4, 3)
    their corner rays, the pyramids' edges (``polyhedron.section_points``).
    Returns the points and the pyramid each belongs to."""
    return section_points(poly, sides, np.zeros(sides.shape[:2]),
                          Edges(np.zeros_like(rays), rays, np.full(rays.shape[:2], np.inf)))


class FacePart(NamedTuple):
    """A cube face's part of P (``cube_sections``)."""
    face: int
    """Its number in CUBE_FACES."""
    points: np.ndarray
    """Points whose convex hull is P ∩ C_face (relative to the apex)."""
    nearest: float
    farthest: float
    """The least and greatest of their depths along the face's axis."""


def cube_sections(poly: ConvexPolytope, basis: np.ndarray) -> list[FacePart]:
    """The parts of P (relative to the apex) in the faces of the cube with
    axes ``basis`` (rows) centred on the apex (``pyramid_sections``), for the
    faces whose part has volume: four points or more, and some of them off
    each of the face's sides (within SNAP tolerances: the section is taken
    within the tolerance, so a pyramid touching P at the apex gets points up
    to about two tolerances from its sides; the points are within the
    tolerance of the pyramid, so the greatest distance from a side is the
    deepest point's inwards)."""
    planes = _FACE_SIDES_AND_AXES @ basis                    # (30, 3): the 6 x 4 sides, then the 6 axes
    pts, face = pyramid_sections(poly, planes[:24].reshape(6, 4, 3), _FACE_RAYS @ basis)
    counts = np.bincount(face, minlength=6).tolist()
    faces = [f for f in range(6) if counts[f]]
    if not faces:
        return []
    ends = list(itertools.accumulate(counts[f] for f in faces))
    starts = [e - counts[f] for f, e in zip(faces, ends)]
    distance = pts @ planes.T                                # to each side (outwards) and along each axis
    least = np.minimum.reduceat(distance, starts).tolist()
    most = np.maximum.reduceat(distance[:, 24:], starts).tolist()
    return [FacePart(f, pts[s:e], lo[24 + f], hi[f]) for f, s, e, lo, hi in zip(faces, starts, ends, least, most)
            if e - s >= 4 and max(lo[4 * f: 4 * f + 4]) < -SNAP * poly.tol]


def light_frames(view: View, light: Light, body: IntersectionBody, options: WarpOptions) -> list[LightFrame]:
    """The frames a light needs for this body, in selection order."""
    if light.is_directional:
        return [sun_frame(view, light, body)]
    return point_frames(view, light, body, options)
