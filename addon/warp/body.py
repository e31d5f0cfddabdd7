"""The intersection body B (Scherzer §4.1, Fig. 5; Stamminger-Drettakis §4.1, H = M ∩ S ∩ L).

    B = hull(R ∪ light) ∩ S_c ∩ L,   R = V ∩ S_r ∩ L

V is the view frustum, L the light's frustum (the spot cone; all space for suns
and point lights), S_r the box around the receivers that meet V, and S_c the box
around R and the casters that meet hull(R ∪ light). This is the papers' B with
the scene box S tightened to what the view needs: a caster outside
hull(R ∪ light) cannot shadow a visible receiver, and a receiver outside V is not
seen. "Model only what a scene needs."

hull(R ∪ light) is built exactly from half-spaces with the light in homogeneous
coordinates (w = 0 for a sun): R's facets that do not face the light, plus one
plane through every silhouette edge and the light. Since L is a convex cone
with its apex at the light and R ⊂ L, hull(R ∪ light) ⊂ L already.

Polytopes are :class:`~.polyhedron.ConvexPolytope` (vertex enumeration from
half-spaces, vectorised), computed relative to the camera position (so
coordinates at 1e5 keep their precision) with tolerances relative to the
scene's scale. Boxes are culled through a two-level index (``BoxIndex``:
clusters of 32 boxes with their bounds, built once per scene), which gives the
same masks as testing every box.

Cost on a 10,000-box scene (``python -m bench.warp_speed``): about 1 ms for a
sun or point light, 1.7 ms for a spot, in plain Python and numpy.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .geometry import cross3
from .polyhedron import COINCIDENT, ConvexPolytope, Plane, cross_rows
from .types import EmptyBodyError, Light, SceneBounds, View

CONE_SIDES = 16
"""The spot cone is bounded by a circumscribed pyramid with this many sides."""

RELATIVE_TOLERANCE = 1e-10
BOX_PAD = 1e-7
"""Boxes are padded by this fraction of the scene scale (and at least 512
tolerances) so a flat scene, or a single point-sized box, still gives a closed
body at least 1000 tolerances thick."""

SUN_FACING = 1e-12
"""A facet faces a sun when cos(angle to the direction towards it) exceeds this."""


class LazyFaces(Sequence):
    """B's faces (world-space vertex loops), computed on first use: methods
    that only need the vertices never pay for ordering the loops."""

    def __init__(self, poly: ConvexPolytope, origin: np.ndarray):
        self._poly, self._origin, self._faces = poly, origin, None

    def _get(self) -> list[np.ndarray]:
        if self._faces is None:
            self._faces = [f + self._origin for f in self._poly.faces()]
        return self._faces

    def __getitem__(self, i):
        return self._get()[i]

    def __len__(self) -> int:
        return len(self._poly.normals)

    def __iter__(self):
        return iter(self._get())

    def __repr__(self) -> str:
        return f"LazyFaces({len(self)} faces)"


@dataclass
class IntersectionBody:
    """B and what it was built from. ``vertices``/``faces`` are in world space."""

    vertices: np.ndarray
    faces: Sequence[np.ndarray]
    """B's faces as world-space vertex loops (counter-clockwise seen from outside)."""
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
    """World-space half-spaces of hull(R ∪ light) (⊂ L): the light-extruded body."""
    tolerance: float = 0.0
    scale: float = 1.0
    polytope: ConvexPolytope | None = None
    """B as a polytope relative to ``origin`` (facet planes, incidence)."""
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    """The point B's ``polytope`` is expressed relative to (the camera position)."""

    @property
    def centroid(self) -> np.ndarray:
        return self.vertices.mean(axis=0)

    def contains(self, points, tol: float | None = None) -> np.ndarray:
        """Which (N, 3) world points lie in B (within ``tol``, default 10x the tolerance)."""
        t = self.tolerance * 10 if tol is None else tol
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if self.polytope is not None:
            return self.polytope.contains(p - self.origin, t)
        from .polyhedron import face_planes
        ok = np.ones(len(p), dtype=bool)
        for pl in face_planes(self.faces):
            ok &= pl.distance(p) <= t
        return ok

    def polytope_from(self, apex) -> ConvexPolytope:
        """B relative to ``apex`` (e.g. a point light), for clipping in its frame."""
        if self.polytope is None:
            raise ValueError("this body has no polytope")
        return self.polytope.translated(self.origin - np.asarray(apex, dtype=np.float64))


def cone_halfspaces(apex, axis, full_angle) -> tuple[np.ndarray, np.ndarray]:
    """(normals (k, 3), offsets (k,)) of a pyramid circumscribing the cone
    (apex, axis, full angle), k = CONE_SIDES."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    u = cross3(a, np.eye(3)[int(np.argmin(np.abs(a)))])
    u /= np.linalg.norm(u)
    v = cross3(a, u)
    half = full_angle / 2
    # Tangent planes of a regular pyramid circumscribing the cone: the cone's
    # half-angle widened so the cone fits inside the polygon (secant of pi/k).
    widened = math.atan(math.tan(half) / math.cos(math.pi / CONE_SIDES))
    phi = 2 * math.pi * np.arange(CONE_SIDES) / CONE_SIDES
    radial = np.cos(phi)[:, None] * u + np.sin(phi)[:, None] * v
    n = math.cos(widened) * radial - math.sin(widened) * a
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return n, n @ np.asarray(apex, dtype=np.float64)


def cone_planes(apex, axis, full_angle) -> list[Plane]:
    """Half-spaces of a pyramid circumscribing the cone (apex, axis, full angle)."""
    n, o = cone_halfspaces(apex, axis, full_angle)
    return [Plane(ni, float(oi)) for ni, oi in zip(n, o)]


def _stack_of(boxes: np.ndarray) -> np.ndarray:
    """(6, N): rows 0-2 the boxes' centres, rows 3-5 their half extents."""
    return np.ascontiguousarray(np.concatenate([(boxes[:, 0] + boxes[:, 1]).T / 2, (boxes[:, 1] - boxes[:, 0]).T / 2]))


def boxes_meeting_arrays(normals, offsets, centre_half: np.ndarray, tol: float = 0.0) -> np.ndarray:
    """Boolean mask of boxes, given as (6, N) centres/half extents, not entirely
    outside any half-space ``normals @ x <= offsets`` (a conservative test)."""
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    count = centre_half.shape[1]
    if count == 0:
        return np.zeros(0, dtype=bool)
    if len(n) == 0:
        return np.ones(count, dtype=bool)
    m = np.concatenate([n, -np.abs(n)], axis=1)
    # (A non-contiguous operand makes matmul fall off BLAS and take 100x longer.)
    nearest = m @ np.ascontiguousarray(centre_half) - np.asarray(offsets, dtype=np.float64)[:, None]
    return nearest.max(axis=0) <= tol


CLUSTER_SIZE = 32
"""Boxes per cluster of the two-level culling index."""


class BoxIndex:
    """A two-level index over a scene's boxes for culling against convex
    regions: boxes grouped in clusters of ``CLUSTER_SIZE`` (the leaves of a
    median-split k-d tree) with their bounding boxes. A cluster wholly
    outside a half-space is rejected, one wholly inside all is accepted, and
    only the boxes of the remaining clusters are tested one by one. The result
    equals the plain per-box test (``boxes_meeting_arrays``)."""

    def __init__(self, boxes: np.ndarray):
        b = np.asarray(boxes, dtype=np.float64).reshape(-1, 2, 3)
        self.count = len(b)
        k = CLUSTER_SIZE
        if self.count == 0:
            self.perm = np.zeros(0, dtype=np.int64)
            self.lo = self.hi = np.zeros((0, 3))
            self.stack = np.zeros((6, 0))
            self.c_lo = self.c_hi = np.zeros((0, 3))
            self.lo_t = self.hi_t = self.c_lo_t = self.c_hi_t = np.zeros((3, 0))
            self.c_stack = np.zeros((6, 0))
            return
        # Clusters: leaves of a median-split k-d tree over the box centres (split
        # along the widest axis of the boxes' extent), so each cluster is compact.
        centre = (b[:, 0] + b[:, 1]) / 2
        leaves: list[np.ndarray] = []
        todo = [np.arange(len(b))]
        while todo:
            ids = todo.pop()
            if len(ids) <= k:
                leaves.append(ids)
                continue
            ext = b[ids, 1].max(axis=0) - b[ids, 0].min(axis=0)
            axis = int(np.argmax(ext))
            half = (len(ids) // (2 * k)) * k or k      # left part: whole clusters
            part = np.argpartition(centre[ids, axis], half - 1)
            todo.append(ids[part[half:]])
            todo.append(ids[part[:half]])
        # Leaves come depth-first, left part first: every leaf but the last is full.
        self.perm = np.concatenate(leaves)
        sb = b[self.perm]
        self.lo, self.hi = np.ascontiguousarray(sb[:, 0]), np.ascontiguousarray(sb[:, 1])
        # (3, N) copies: numpy reduces along a long last axis far faster than over (N, 3) rows.
        self.lo_t, self.hi_t = np.ascontiguousarray(self.lo.T), np.ascontiguousarray(self.hi.T)
        self.stack = _stack_of(sb)
        n_c = -(-self.count // k)
        pad = n_c * k - self.count
        plo = np.concatenate([self.lo, np.repeat(self.lo[-1:], pad, axis=0)]).reshape(n_c, k, 3)
        phi = np.concatenate([self.hi, np.repeat(self.hi[-1:], pad, axis=0)]).reshape(n_c, k, 3)
        self.c_lo, self.c_hi = plo.min(axis=1), phi.max(axis=1)
        self.c_lo_t, self.c_hi_t = np.ascontiguousarray(self.c_lo.T), np.ascontiguousarray(self.c_hi.T)
        self.c_stack = _stack_of(np.stack([self.c_lo, self.c_hi], axis=1))

    @classmethod
    def of(cls, scene: SceneBounds, which: str) -> "BoxIndex":
        """The index of ``scene.casters`` or ``scene.receivers`` (built once per scene)."""
        def build():
            boxes = getattr(scene, which)
            other = scene.receivers if which == "casters" else scene.casters
            if other is boxes or (other.shape == boxes.shape and np.array_equal(other, boxes)):
                return scene.cached(("BoxIndex", "boxes"), lambda: cls(boxes))
            return cls(boxes)
        return scene.cached(("BoxIndex", which), build)

    def cull(self, normals, offsets, tol: float = 0.0) -> tuple[np.ndarray, np.ndarray | None]:
        """(mask over the boxes in their original order, the (2, 3) bounding box
        of the boxes that meet the region or None)."""
        n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        o = np.asarray(offsets, dtype=np.float64).reshape(-1, 1)
        mask = np.zeros(self.count, dtype=bool)
        if self.count == 0:
            return mask, None
        an = np.abs(n)
        centre_part = n @ self.c_stack[:3] - o
        spread = an @ self.c_stack[3:]
        c_out = (centre_part - spread).max(axis=0) > tol      # wholly outside some half-space
        c_in = (centre_part + spread).max(axis=0) <= tol      # wholly inside every half-space
        k = CLUSTER_SIZE
        sorted_mask = np.repeat(c_in, k)[: self.count]
        edge = np.nonzero(~c_out & ~c_in)[0]
        if len(edge):
            idx = (edge[:, None] * k + np.arange(k)).ravel()
            idx = idx[idx < self.count]
            hit = boxes_meeting_arrays(n, o[:, 0], np.take(self.stack, idx, axis=1), tol)
            sorted_mask[idx[hit]] = True
            idx = idx[hit]
        else:
            idx = edge
        mask[self.perm] = sorted_mask
        if not sorted_mask.any():
            return mask, None
        lo = np.concatenate([self.c_lo_t[:, c_in], np.take(self.lo_t, idx, axis=1)], axis=1).min(axis=1)
        hi = np.concatenate([self.c_hi_t[:, c_in], np.take(self.hi_t, idx, axis=1)], axis=1).max(axis=1)
        return mask, np.array([lo, hi])


def boxes_meeting(planes: list[Plane], boxes: np.ndarray, tol: float = 0.0) -> np.ndarray:
    """Boolean mask of (N, 2, 3) boxes not entirely outside any half-space (a
    conservative box/convex-body overlap test)."""
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 2, 3)
    if not planes:
        return np.ones(len(b), dtype=bool)
    n = np.array([p.normal for p in planes])
    o = np.array([p.offset for p in planes])
    return boxes_meeting_arrays(n, o, _stack_of(b), tol)


def light_halfspaces(light: Light, origin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """L relative to ``origin``: the half-spaces of the light's frustum (only spots have one)."""
    if light.type != "SPOT":
        return np.zeros((0, 3)), np.zeros(0)
    return cone_halfspaces(light.position - origin, light.direction, light.spot_angle)


def light_planes(light: Light, origin: np.ndarray) -> list[Plane]:
    """L: the half-spaces of the light's frustum (only spots have one)."""
    n, o = light_halfspaces(light, origin)
    return [Plane(ni, float(oi)) for ni, oi in zip(n, o)]


def hull_with_light(faces: list[np.ndarray], light_h: np.ndarray, tol: float) -> list[Plane]:
    """Half-spaces of hull(P ∪ light) for a convex polyhedron P given as faces
    (see ``hull_halfspaces``), light in homogeneous coordinates (x, y, z, w)."""
    poly = ConvexPolytope.from_faces(faces, tol)
    if poly is None:
        return []
    n, o = hull_halfspaces(poly, light_h, tol)
    return [Plane(ni, float(oi)) for ni, oi in zip(n, o)]


def hull_halfspaces(poly: ConvexPolytope, light_h: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Half-spaces (normals, offsets) of hull(P ∪ light) for a convex polytope P,
    the light in homogeneous coordinates (x, y, z, w), w = 0 for a light at
    infinity: P's facets not facing the light plus a plane through each
    silhouette edge (facing facet on one side, non-facing on the other) and the
    light. A silhouette plane too ill-defined to orient (light on the edge's
    line) is left out, which only makes the hull larger (conservative)."""
    n, o = poly.normals, poly.offsets
    s = n @ light_h[:3] - o * light_h[3]
    facing = s > (tol if light_h[3] != 0 else SUN_FACING)
    edges, facets = poly.edges()
    sil = facing[facets[:, 0]] != facing[facets[:, 1]]
    a = poly.vertices[edges[sil, 0]]
    b = poly.vertices[edges[sil, 1]]
    to_light = light_h[:3] - a * light_h[3]
    sn = cross_rows(b - a, to_light)
    length = np.linalg.norm(sn, axis=1)
    ok = length > 1e-12 * np.linalg.norm(b - a, axis=1) * np.linalg.norm(to_light, axis=1)
    sn = sn[ok] / length[ok, None]
    so = np.einsum("ij,ij->i", sn, a[ok])
    flip = sn @ poly.centroid - so > 0
    sn[flip], so[flip] = -sn[flip], -so[flip]
    # A true silhouette plane supports P (all of P on its inner side). One that
    # cuts P can only come from an edge of faces that did not close on a
    # near-degenerate cut (polyhedron.COINCIDENT); leaving it out is conservative.
    supports = (poly.vertices @ sn.T - so).max(axis=0, initial=-np.inf) <= COINCIDENT * tol
    sn, so = sn[supports], so[supports]
    return np.concatenate([n[~facing], sn]), np.concatenate([o[~facing], so])


def _pad(box: np.ndarray, amount: float) -> np.ndarray:
    return np.array([box[0] - amount, box[1] + amount])


def _view_halfspaces(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Outward (normals, offsets) of the view frustum's six faces from its corners."""
    poly = ConvexPolytope.from_corners(corners, 0.0)
    return poly.normals, poly.offsets


def intersection_body(view: View, light: Light, scene: SceneBounds) -> IntersectionBody:
    """B for this view, light and scene (Scherzer §4.1). Raises EmptyBodyError
    (with the reason) when nothing visible can receive a shadow."""
    if scene.is_empty:
        raise EmptyBodyError("the scene has no shadow casters or receivers")
    origin = view.position
    corners = view.corners() - origin
    view_size = float(np.linalg.norm(corners[0] - corners[7]))
    v_tol = RELATIVE_TOLERANCE * view_size
    v_poly = ConvexPolytope.from_corners(corners, v_tol)
    ln, lo = light_halfspaces(light, origin)
    cone = " and the spot cone" if len(ln) else ""
    if len(ln):
        # Only the cone's planes that cut V matter for V ∩ L (V is convex).
        d = ln @ v_poly.vertices.T - lo[:, None]
        if np.any(d.min(axis=1) >= 0):
            raise EmptyBodyError("no shadow receiver is lit in view: the view frustum is outside the spot cone")
        cuts = d.max(axis=1) > 0
        ln, lo = ln[cuts], lo[cuts]

    # Receivers meeting V ∩ L (planes moved to world space for the culling).
    vn = np.concatenate([v_poly.normals, ln])
    vo = np.concatenate([v_poly.offsets, lo])
    receiver_mask, s_r = BoxIndex.of(scene, "receivers").cull(vn, vo + vn @ origin)
    if s_r is None:
        raise EmptyBodyError("no shadow receiver is inside the view frustum" + cone)
    s_r = s_r - origin
    scale = float(max(np.linalg.norm(s_r[1] - s_r[0]), view_size * 1e-6, 1e-9))
    tol = RELATIVE_TOLERANCE * max(scale, float(np.abs(s_r).max()))
    s_r = _pad(s_r, max(BOX_PAD * scale, 512 * tol))

    # R = V ∩ S_r ∩ L.
    eye3 = np.eye(3)
    box_n = np.concatenate([-eye3, eye3])
    v_poly = ConvexPolytope(v_poly.vertices, v_poly.normals, v_poly.offsets, v_poly.incidence, tol)
    # (One clip: each clip costs more in fixed overhead than in the plane triples it solves.)
    visible = v_poly.clip(np.concatenate([box_n, ln]), np.concatenate([-s_r[0], s_r[1], lo]))
    if visible is None:
        raise EmptyBodyError("the view frustum does not meet the receivers" + (" inside the spot cone" if len(ln) else ""))

    # hull(R ∪ light) ∩ L, and the casters meeting it.
    light_h = light.homogeneous_position.copy()
    if light_h[3] != 0:
        light_h[:3] -= origin
    # hull(R ∪ light) ⊂ L already (L is a convex cone with its apex at the light and R ⊂ L),
    # so L's planes would only repeat what the hull says.
    hn, ho = hull_halfspaces(visible, light_h, tol)
    caster_mask, cast_box = BoxIndex.of(scene, "casters").cull(hn, ho + hn @ origin, tol)
    s_c = np.array([visible.vertices.min(axis=0), visible.vertices.max(axis=0)])
    if cast_box is not None:
        s_c = np.array([np.minimum(s_c[0], cast_box[0] - origin), np.maximum(s_c[1], cast_box[1] - origin)])
    scale = float(max(np.linalg.norm(s_c[1] - s_c[0]), scale))
    s_c = _pad(s_c, max(BOX_PAD * scale, 512 * tol))

    body = ConvexPolytope.box(s_c[0], s_c[1], tol).clip(hn, ho)
    if body is None:
        raise EmptyBodyError("the light-extruded view does not meet the scene")
    return IntersectionBody(
        vertices=body.vertices + origin,
        faces=LazyFaces(body, origin),
        visible_vertices=visible.vertices + origin,
        caster_mask=caster_mask,
        receiver_mask=receiver_mask,
        receiver_boxes=np.compress(receiver_mask, scene.receivers, axis=0),   # a copy; 4x faster than a boolean gather
        hull_planes=[Plane(n, float(o)) for n, o in zip(hn, ho + hn @ origin)],
        tolerance=tol,
        scale=scale,
        polytope=body,
        origin=origin,
    )
