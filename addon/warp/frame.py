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

import functools
import itertools
import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .body import IntersectionBody
from .geometry import across, cross3, dot3, homogeneous, look_along, normalize, perpendicular
from .types import Light, View, WarpOptions

PARALLEL_BLEND = math.sin(math.radians(1.0))
"""Below this |projected view direction| the camera's up vector takes over."""

FLIP_Z = np.diag([1.0, 1.0, -1.0, 1.0])


@dataclass(frozen=True)
class LightFrame:
    """``to_light``: world -> light space (projective for point lights);
    ``points``: world-space vertices of the part of B this frame serves;
    ``role``: "main" or "cube+X" etc.; ``directional``: orthographic frame."""

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
    pr = across(cross3(v, u).tolist(), d)
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
    return min(gamma, math.pi - gamma), gamma


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


def perspective_frame(apex, axis, up_hint, points, role, scale) -> LightFrame:
    """A point light's perspective looking along ``axis`` from ``apex``:
    eye space -> (x, y, z_gl, -z) so rays from the apex become parallel to z.
    The near plane is the nearest point's depth, clamped to a scale-relative
    minimum when the light sits inside the body."""
    view = look_along(apex, axis, up_hint)
    depth = (points - apex) @ -view[2, :3]                   # along the axis (the eye looks down -z)
    near, far, clamped = near_far(float(depth.min()), float(depth.max()), 1e-6 * scale)
    return LightFrame(perspective_of(view, near, far), points, role, False, clamped)


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

    The switch between the two is a known discontinuity (the number of maps
    changes), at ``2 * light_cone(B)[1] == max_frustum_angle``."""
    apex = light.position
    axis, half = light_cone(body.vertices, apex)
    up = image_up(view.direction, view.up, axis)
    if not up.any():
        up = perpendicular(axis)
    if 2 * half <= options.max_frustum_angle and not body.contains(apex[None])[0]:     # (not inside B)
        return [perspective_frame(apex, axis, up, body.vertices, "main", body.scale)]
    basis = cube_basis(axis.tolist(), up.tolist())
    poly = body.polytope_from(apex)
    near_floor = 1e-6 * body.scale
    pts, member = cube_sections(poly, poly.edges(), basis)
    # The faces B reaches, each with its run of candidates (face by face) and its depths along the face's axis.
    counts = member.sum(axis=0).tolist()
    faces = [f for f in range(6) if counts[f]]
    ends = list(itertools.accumulate(counts[f] for f in faces))
    starts = [e - counts[f] for f, e in zip(faces, ends)]
    _, candidate = np.nonzero(member.T)
    rel = pts[candidate]                                     # relative to the apex
    turns = _FACE_TURNS @ basis                              # (6, 3, 3): rows x, y, -forward
    depth = -(pts @ turns[:, 2].T).T[member.T]               # along each face's forward
    nearest, farthest = np.minimum.reduceat(depth, starts).tolist(), np.maximum.reduceat(depth, starts).tolist()
    world = rel + apex
    rows, shifts = turns.tolist(), (-(turns @ apex)).tolist()   # each face's view: rotation rows, translation
    frames, entries = [], []
    for f, s, e, n, fa in zip(faces, starts, ends, nearest, farthest):
        points, clamped = world[s:e], n < near_floor
        if clamped:
            # B reaches the light inside this face: the whole face from the near floor on.
            forward = -turns[f, 2]
            others = np.delete(basis, CUBE_FACES[f][1], axis=0)
            corners = near_floor * (forward + _FACE_CORNERS @ others)
            face_pts = np.concatenate([rel[s:e][depth[s:e] >= near_floor], corners])
            fa = float((face_pts @ forward).max())
            points = face_pts + apex
        # The face's view (rows x, y, -forward through the apex) and perspective, entry by entry.
        near, far, _ = near_far(n, fa, near_floor)
        a, b = depth_coefficients(near, far)
        (x, y, (z0, z1, z2)), (tx, ty, tz) = rows[f], shifts[f]
        entries += x + [tx] + y + [ty] + [a * z0, a * z1, a * z2, a * tz + b, -z0, -z1, -z2, -tz]
        frames.append((f, points, clamped))
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
_CUBE_SIGNS = np.array([[sx, sy, sz] for sx in (-1.0, 1.0) for sy in (-1.0, 1.0) for sz in (-1.0, 1.0)])
"""The cube's 8 corner rays (in its basis), each a corner ray of the 3 faces whose signs it shares."""
_FACE_PLANES = np.array([[s if j == o else (-sign if j == k else 0.0) for j in range(3)]
                         for _, k, sign in CUBE_FACES for o in range(3) if o != k for s in (1.0, -1.0)])
"""Coefficients (in the cube's basis) of the 4 side planes of each face's
pyramid, s·other - forward (not yet unit): face f owns rows 4f .. 4f + 3."""
_CUBE_PLANES = np.array([[1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, -1.0],
                         [0.0, 1.0, 1.0], [-1.0, 0.0, 1.0], [1.0, 0.0, 1.0]])
"""The planes x = ±y, y = ±z, z = ±x (in the cube's basis, not yet unit): the
24 sides of the faces' pyramids are these 6, each shared by four faces."""
_CUBE_UNIT_PLANES_AND_RAYS = np.concatenate([_CUBE_PLANES / math.sqrt(2.0), _CUBE_SIGNS])
"""The 6 planes' unit normals and the 8 corner rays: one product with the basis gives both."""


@dataclass(frozen=True, eq=False)
class Pyramids:
    """How k four-sided pyramids with their apex at the origin are bounded by
    m planes and r corner rays that neighbouring pyramids may share: pyramid j
    is {x : signs[j, i] · n_p . x <= 0 for p = sides[j, i], i = 0..3} (n_p the
    planes' normals), and ``corners[c, j]`` says whether ray c is one of its
    corner rays. Made once and shared (read-only arrays)."""

    sides: np.ndarray      # (k, 4) plane numbers
    signs: np.ndarray      # (k, 4) ±1
    corners: np.ndarray    # (r, k) bool
    uses: np.ndarray = field(init=False)
    """(m, k): whether plane p is one of pyramid j's sides."""
    separate: bool = field(init=False)
    """Pyramid j has planes 4j .. 4j + 3 with signs +1 (nothing shared): its
    sides' distances are a reshape of the planes'."""

    def __post_init__(self):
        uses = (self.sides[None] == np.arange(self.sides.max() + 1)[:, None, None]).any(axis=2)
        object.__setattr__(self, "uses", uses)
        object.__setattr__(self, "separate", bool(np.array_equal(self.sides.ravel(), np.arange(self.sides.size))
                                                  and (self.signs == 1.0).all()))
        for a in (self.sides, self.signs, self.corners, uses):
            a.flags.writeable = False


@functools.lru_cache(maxsize=None)
def separate_pyramids(k: int) -> Pyramids:
    """k pyramids that share nothing: pyramid j has the planes and corner rays
    4j .. 4j + 3 (made once per count)."""
    return Pyramids(np.arange(4 * k).reshape(k, 4), np.ones((k, 4)), np.eye(k, dtype=bool).repeat(4, axis=0))


def _cube_pyramids() -> Pyramids:
    overlap = (_FACE_PLANES @ _CUBE_PLANES.T) / 2.0         # ±1 where a face's side is ± that plane, |.| <= 1/2 else
    sides = np.abs(overlap).argmax(axis=1)
    corners = _CUBE_SIGNS[:, [k for _, k, _ in CUBE_FACES]] == [sign for _, _, sign in CUBE_FACES]
    return Pyramids(sides.reshape(6, 4), overlap[np.arange(24), sides].reshape(6, 4), corners)


CUBE_PYRAMIDS = _cube_pyramids()
"""The six faces' pyramids: each face's sides (``_FACE_PLANES``) are ± one of
``_CUBE_PLANES``, its corner rays the 4 of ``_CUBE_SIGNS`` whose sign on its axis is the face's."""


def cube_section_points(poly, edges: np.ndarray, basis: np.ndarray) -> list:
    """For each face of the cube with axes ``basis`` (rows) centred on the
    apex, points whose convex hull is P ∩ C_face (``pyramid_section_points``,
    all six at once), or None when that part has no volume."""
    pts, member = cube_sections(poly, edges, basis)
    return [pts[member[:, f]] if member[:, f].any() else None for f in range(6)]


def cube_sections(poly, edges: np.ndarray, basis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``cube_section_points`` as candidate points (n, 3) and which faces each
    belongs to (n, 6), a face's column all False when its part has no volume.
    The faces' pyramids share their 6 planes and 8 corner rays
    (``CUBE_PYRAMIDS``), so each crossing and each ray is found once."""
    tol = poly.tol
    planes_rays = _CUBE_UNIT_PLANES_AND_RAYS @ basis
    pts, member, dist = pyramid_sections(poly, edges, planes_rays[:6], planes_rays[6:], CUBE_PYRAMIDS)
    # No volume: too few points, or all on one of the face's sides (none of its points off that plane).
    off = member.T @ (np.abs(dist) > tol)                    # (faces, planes): some point of the face is off the plane
    flat = (CUBE_PYRAMIDS.uses.T & ~off).any(axis=1)
    return pts, member & ((member.sum(axis=0) >= 4) & ~flat)


def pyramid_sections(poly, edges: np.ndarray, planes: np.ndarray, rays: np.ndarray,
                     pyramids: Pyramids) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """P ∩ C_j for k four-sided pyramids C_j with their apex at the origin (P
    relative to the apex, e.g. a point light), all at once, without clipping.
    ``planes`` (m, 3) are the unit normals of their sides and ``rays`` (r, 3)
    their corner rays (pointing into the pyramids they bound), shared as
    ``pyramids`` says. Returns candidate points (n, 3), which pyramids each
    belongs to (n, k), a column all False when P lies outside one side of C_j,
    and the candidates' signed distances to the planes (n, m).

    Every vertex of P ∩ C_j is among its points: P's vertices inside C_j, the
    crossings of P's edges with C_j's sides (kept if inside C_j), where C_j's
    corner rays enter and leave P, and the apex if P holds it."""
    tol = poly.tol
    v = poly.vertices
    d = v @ planes.T                                         # (vertices, m)
    # P's edges crossing the planes (one end beyond tol on each side).
    da, db = d[edges.T]                                      # (e, m) at either end
    e, p = np.nonzero((np.minimum(da, db) < -tol) & (np.maximum(da, db) > tol))
    da = da[e, p]
    t = da / (da - db[e, p])
    a, b = v[edges[e].T]
    x = a + t[:, None] * (b - a)
    # The corner rays through P: t-interval where n . (t r) <= o for every facet.
    t_lo, t_hi, hit = ray_interval(poly, rays)
    apex = poly.offsets.min() >= -tol                        # P holds the apex: n . 0 - o <= tol for every facet
    pts = np.concatenate([v, x, t_lo[:, None] * rays, t_hi[:, None] * rays, _ORIGIN])
    # Each candidate belongs to the pyramids that hold it among those it was made for: a vertex
    # to all, a crossing to those with its plane as a side, a ray's ends to those it bounds.
    dist = pts @ planes.T                                    # (n, m)
    k = len(pyramids.sides)
    if pyramids.separate:                                    # (n, k, 4) to each pyramid's sides, outward
        side = dist.reshape(len(pts), k, 4)
    else:
        side = dist[:, pyramids.sides] * pyramids.signs
    on_ray = pyramids.corners & hit[:, None]
    made_for = np.concatenate([np.ones((len(v), k), dtype=bool), pyramids.uses[p], on_ray, on_ray, [[apex] * k]])
    outside = np.logical_and.reduce(side[:len(v)] >= -tol, axis=0).any(axis=1)   # (k,): P wholly outside one side
    return pts, (np.maximum.reduce(side, axis=2) <= tol) & made_for & ~outside, dist


_ORIGIN = np.zeros((1, 3))


def ray_interval(poly, rays) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where rays t·r (t >= 0, from the origin, e.g. a point light) run inside the
    polytope: (t_lo, t_hi, hit) with n . (t r) <= o for every facet on [t_lo, t_hi]."""
    denom = rays @ poly.normals.T                            # (R, F): a ray's facets along a row
    o = poly.offsets
    ratio = np.divide(o, denom, out=None, where=denom != 0)           # (left unset where denom = 0, never read)
    t_hi = np.minimum.reduce(ratio, axis=1, where=denom > 0, initial=np.inf)
    t_lo = np.maximum.reduce(ratio, axis=1, where=denom < 0, initial=0.0)   # (and t >= 0)
    hit = (t_lo <= t_hi) & np.isfinite(t_hi)
    if not denom.all():                                      # parallel to a facet and outside it: no hit
        hit &= ~((denom == 0) & (o < 0)).any(axis=1)
    return t_lo, t_hi, hit


def pyramid_section_points(poly, edges: np.ndarray, forward, others) -> np.ndarray | None:
    """Points whose convex hull is P ∩ C for a polytope P (coordinates relative
    to the apex) and the 90° pyramid C = {|o . x| <= forward . x for o in
    others} (a cube face seen from its centre), or None when P ∩ C has no
    volume. They are the vertices of P inside C, the crossings of P's edges
    with C's four planes, where C's four corner rays enter and leave P, and the
    apex if P holds it: every vertex of P ∩ C is among them, so a map fitted to
    them holds P ∩ C. (Vectorised; no clipping.)"""
    tol = poly.tol
    n4 = np.array([s * o - forward for o in others for s in (1.0, -1.0)]) / math.sqrt(2.0)
    v = poly.vertices
    d = v @ n4.T                                             # (n, 4), <= 0 inside C
    if np.any(np.all(d >= -tol, axis=0)):
        return None                                          # P lies outside one plane of C
    pts = [v[d.max(axis=1) <= tol]]
    # P's edges crossing C's planes.
    da, db = d[edges[:, 0]], d[edges[:, 1]]                  # (e, 4)
    cross = ((da < -tol) & (db > tol)) | ((da > tol) & (db < -tol))
    if cross.any():
        e, p = np.nonzero(cross)
        t = da[e, p] / (da[e, p] - db[e, p])
        a = v[edges[e, 0]]
        x = a + t[:, None] * (v[edges[e, 1]] - a)
        pts.append(x[(x @ n4.T).max(axis=1) <= tol])
    # C's corner rays through P: t-interval where n . (t r) <= o for every facet.
    rays = np.array([forward + a * others[0] + b * others[1] for a in (-1.0, 1.0) for b in (-1.0, 1.0)])
    t_lo, t_hi, hit = ray_interval(poly, rays)
    if hit.any():
        pts.append(np.concatenate([t_lo[hit, None] * rays[hit], t_hi[hit, None] * rays[hit]]))
    if poly.contains(np.zeros((1, 3)), tol)[0]:
        pts.append(np.zeros((1, 3)))
    pts = np.concatenate(pts)
    if len(pts) < 4:
        return None
    # No volume: every point on one of C's planes.
    if np.any(np.all(np.abs(pts @ n4.T) <= tol, axis=0)):
        return None
    return pts


def light_frames(view: View, light: Light, body: IntersectionBody, options: WarpOptions) -> list[LightFrame]:
    """The frames a light needs for this body, in selection order."""
    if light.is_directional:
        return [sun_frame(view, light, body)]
    return point_frames(view, light, body, options)
