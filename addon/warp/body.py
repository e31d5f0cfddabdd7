"""The intersection body B (Scherzer §4.1, Fig. 5; Stamminger-Drettakis §4.1, H = M ∩ S ∩ L).

    B = hull(R ∪ light) ∩ S_c ∩ L,   R = V ∩ S_r ∩ L

V is the view frustum, L the light's frustum (the spot cone; all space for suns
and point lights), S_r the box around the receivers that meet V, and S_c the box
around R and the casters that meet hull(R ∪ light). This is the papers' B with
the scene box S tightened to what the view needs: a caster outside
hull(R ∪ light) cannot shadow a visible receiver, and a receiver outside V is not
seen. "Model only what a scene needs."

hull(R ∪ light) is built exactly from half-spaces with the light in homogeneous
coordinates (w = 0 for a sun): R's faces that do not face the light, plus one
plane through every silhouette edge and the light.

Everything is computed relative to the camera position (so coordinates at 1e5
keep their precision) with tolerances relative to the scene's scale.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .polyhedron import Plane, box_faces, clip_faces, face_edges, face_planes, hexahedron_faces, unique_points
from .types import EmptyBodyError, Light, SceneBounds, View

CONE_SIDES = 16
"""The spot cone is bounded by a circumscribed pyramid with this many sides."""

RELATIVE_TOLERANCE = 1e-10
BOX_PAD = 1e-7
"""Boxes are padded by this fraction of the scene scale so a flat scene still
gives a closed body of positive volume."""


@dataclass
class IntersectionBody:
    """B and what it was built from. ``vertices``/``faces`` are in world space."""

    vertices: np.ndarray
    faces: list[np.ndarray]
    visible_vertices: np.ndarray
    """R = V ∩ S_r ∩ L: the part of the view that holds receivers."""
    caster_mask: np.ndarray
    """Which of ``scene.casters`` meet hull(R ∪ light) ∩ L (can shadow what is seen)."""
    receiver_mask: np.ndarray
    """Which of ``scene.receivers`` meet V ∩ L."""
    receiver_boxes: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 3)))
    """World-space boxes of the receivers that meet V ∩ L (``scene.receivers[receiver_mask]``),
    e.g. for plane_optimal's default plane of interest."""
    hull_planes: list[Plane] = field(default_factory=list)
    """World-space half-spaces of hull(R ∪ light) ∩ L: the light-extruded body."""
    tolerance: float = 0.0
    scale: float = 1.0

    @property
    def centroid(self) -> np.ndarray:
        return self.vertices.mean(axis=0)

    def contains(self, points, tol: float | None = None) -> np.ndarray:
        t = self.tolerance * 10 if tol is None else tol
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        ok = np.ones(len(p), dtype=bool)
        for pl in face_planes(self.faces):
            ok &= pl.distance(p) <= t
        return ok


def cone_planes(apex, axis, full_angle) -> list[Plane]:
    """Half-spaces of a pyramid circumscribing the cone (apex, axis, full angle)."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    u = np.cross(a, np.eye(3)[int(np.argmin(np.abs(a)))])
    u /= np.linalg.norm(u)
    v = np.cross(a, u)
    half = full_angle / 2
    # Tangent planes of a regular pyramid circumscribing the cone: the cone's
    # half-angle widened so the cone fits inside the polygon (secant of pi/k).
    widened = math.atan(math.tan(half) / math.cos(math.pi / CONE_SIDES))
    planes = []
    for k in range(CONE_SIDES):
        phi = 2 * math.pi * k / CONE_SIDES
        radial = math.cos(phi) * u + math.sin(phi) * v
        n = math.cos(widened) * radial - math.sin(widened) * a
        planes.append(Plane.through(apex, n))
    return planes


def boxes_meeting(planes: list[Plane], boxes: np.ndarray, tol: float = 0.0) -> np.ndarray:
    """Boolean mask of (N, 2, 3) boxes not entirely outside any half-space (a
    conservative box/convex-body overlap test)."""
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 2, 3)
    if len(b) == 0:
        return np.zeros(0, dtype=bool)
    centre = (b[:, 0] + b[:, 1]) / 2
    half = (b[:, 1] - b[:, 0]) / 2
    ok = np.ones(len(b), dtype=bool)
    for p in planes:
        nearest = centre @ p.normal - half @ np.abs(p.normal) - p.offset
        ok &= nearest <= tol
    return ok


def _aabb(points) -> np.ndarray:
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return np.array([p.min(axis=0), p.max(axis=0)])


def _union_box(boxes: np.ndarray) -> np.ndarray:
    return np.array([boxes[:, 0].min(axis=0), boxes[:, 1].max(axis=0)])


def light_planes(light: Light, origin: np.ndarray) -> list[Plane]:
    """L: the half-spaces of the light's frustum (only spots have one)."""
    if light.type != "SPOT":
        return []
    return cone_planes(light.position - origin, light.direction, light.spot_angle)


def hull_with_light(faces: list[np.ndarray], light_h: np.ndarray, tol: float) -> list[Plane]:
    """Half-spaces of hull(P ∪ light) for a convex polyhedron P, light in
    homogeneous coordinates (x, y, z, w) with w = 0 for a light at infinity."""
    planes = face_planes(faces)
    s = [p.normal @ light_h[:3] - p.offset * light_h[3] for p in planes]
    facing = [si > tol * (1.0 if light_h[3] != 0 else 0.0) + (0.0 if light_h[3] != 0 else 1e-12) for si in s]
    out = [p for p, f in zip(planes, facing) if not f]
    centre = np.mean(np.concatenate(faces), axis=0)
    for a, b, i, j in face_edges(faces, tol):
        if facing[i] == facing[j]:
            continue
        to_light = light_h[:3] - a * light_h[3]
        n = np.cross(b - a, to_light)
        if np.linalg.norm(n) <= 1e-14 * max(np.linalg.norm(b - a) * np.linalg.norm(to_light), 1e-300):
            continue
        p = Plane.through(a, n)
        if p.distance(centre[None])[0] > 0:
            p = Plane(-p.normal, -p.offset)
        out.append(p)
    return out


def _pad(box: np.ndarray, amount: float) -> np.ndarray:
    return np.array([box[0] - amount, box[1] + amount])


def intersection_body(view: View, light: Light, scene: SceneBounds) -> IntersectionBody:
    """B for this view, light and scene (Scherzer §4.1). Raises EmptyBodyError
    (with the reason) when nothing visible can receive a shadow."""
    if scene.is_empty:
        raise EmptyBodyError("the scene has no shadow casters or receivers")
    origin = view.position
    receivers = scene.receivers - origin
    casters = scene.casters - origin
    v_faces = hexahedron_faces(view.corners() - origin)
    v_planes = face_planes(v_faces)
    l_planes = light_planes(light, origin)

    receiver_mask = boxes_meeting(v_planes + l_planes, receivers)
    if not receiver_mask.any():
        raise EmptyBodyError("no shadow receiver is inside the view frustum" + (" and the spot cone" if l_planes else ""))
    s_r = _union_box(receivers[receiver_mask])
    scale = float(max(np.linalg.norm(s_r[1] - s_r[0]), np.linalg.norm(view.corners()[0] - view.corners()[7]) * 1e-6, 1e-9))
    tol = RELATIVE_TOLERANCE * max(scale, float(np.abs(s_r).max()))
    s_r = _pad(s_r, BOX_PAD * scale)

    visible = v_faces
    for p in face_planes(box_faces(*s_r)) + l_planes:
        visible = clip_faces(visible, p, tol)
        if not visible:
            raise EmptyBodyError("the view frustum does not meet the receivers" + (" inside the spot cone" if l_planes else ""))

    light_h = light.homogeneous_position.copy()
    if light_h[3] != 0:
        light_h[:3] -= origin
    h_planes = hull_with_light(visible, light_h, tol) + l_planes
    caster_mask = boxes_meeting(h_planes, casters, tol)
    visible_pts = np.concatenate(visible)
    s_c = _aabb(visible_pts)
    if caster_mask.any():
        s_c = _union_box(np.concatenate([s_c[None], casters[caster_mask]]))
    scale = float(max(np.linalg.norm(s_c[1] - s_c[0]), scale))
    s_c = _pad(s_c, BOX_PAD * scale)

    faces = box_faces(*s_c)
    for p in h_planes:
        faces = clip_faces(faces, p, tol)
        if not faces:
            raise EmptyBodyError("the light-extruded view does not meet the scene")
    world_faces = [f + origin for f in faces]
    vertices = unique_points(np.concatenate(faces), tol * 10) + origin
    world_planes = [Plane(p.normal, p.offset + float(p.normal @ origin)) for p in h_planes]
    return IntersectionBody(
        vertices=vertices,
        faces=world_faces,
        visible_vertices=unique_points(visible_pts, tol * 10) + origin,
        caster_mask=caster_mask,
        receiver_mask=receiver_mask,
        receiver_boxes=scene.receivers[receiver_mask].copy(),
        hull_planes=world_planes,
        tolerance=tol,
        scale=scale,
    )
