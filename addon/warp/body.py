"""The intersection body B (Scherzer §4.1, Fig. 5; Stamminger-Drettakis §4.1, H = M ∩ S ∩ L).

    B = hull(R ∪ light) ∩ S_c ∩ L,   R = V ∩ S_r ∩ L

V is the view frustum, L the light's frustum (the spot cone; all space for suns
and point lights), S_r the box around the receivers that meet V, and S_c the box
around R and the casters that meet hull(R ∪ light). This is the papers' B with
the scene box S tightened to what the view needs: a caster outside
hull(R ∪ light) cannot shadow a visible receiver, and a receiver outside V is not
seen. "Model only what a scene needs."

hull(R ∪ light) is built exactly, with the light in homogeneous coordinates
(w = 0 for a sun): R's facets that do not face the light, plus through every
silhouette edge the plane through that edge and the light, a positive
combination of the edge's two facets (``light_hull``). Since L is a convex cone
with its apex at the light and R ⊂ L, hull(R ∪ light) ⊂ L already.

The polyhedra are face loops in plain Python floats (:mod:`.brep`): R is the
frustum cut by S_r's and L's planes, the hull is R's silhouette joined to the
light (for a sun, extruded to a cap beyond S_c), and B is the hull cut by S_c's
planes; each cut closes its faces by construction. A cut too degenerate for the
face walk falls back to vertex enumeration (:class:`~.polyhedron.ConvexPolytope`).
Everything is computed relative to the camera position (so coordinates at 1e5
keep their precision) with tolerances relative to the scene's scale. Boxes are
culled through a two-level index (``BoxIndex``: clusters of 32 boxes with their
bounds, built once per scene), which gives the same masks as testing every box.

Cost on a 10,000-box scene (``make bench``): see docs/performance.md.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from .geometry import cross3
from . import brep
from .brep import Brep, OpenCut, directed_edges
from .polyhedron import ConvexPolytope, Plane
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


class Selection(NamedTuple):
    """The boxes of a ``BoxIndex`` that meet a convex region, kept in the
    index's own order; the mask over the scene's boxes is made on demand."""

    index: "BoxIndex"
    selected: np.ndarray
    """Which boxes meet the region, in the index's (cluster) order."""
    box: np.ndarray | None
    """The (2, 3) bounding box of those boxes, or None when there are none."""

    @property
    def mask(self) -> np.ndarray:
        """Which of the indexed boxes (in their original order) meet the region."""
        mask = np.zeros(self.index.count, dtype=bool)
        mask[self.index.perm] = self.selected
        return mask


@dataclass
class IntersectionBody:
    """B and what it was built from. ``vertices``/``faces`` are in world space.
    The culling results (``caster_mask``, ``receiver_mask``, ``receiver_boxes``,
    ``hull_planes``) are made on first use."""

    vertices: np.ndarray
    faces: Sequence[np.ndarray]
    """B's faces as world-space vertex loops (counter-clockwise seen from outside)."""
    visible_vertices: np.ndarray
    """R = V ∩ S_r ∩ L: the part of the view that holds receivers."""
    casters: Selection
    """The casters that meet hull(R ∪ light) ∩ L (can shadow what is seen)."""
    receivers: Selection
    """The receivers that meet V ∩ L."""
    receiver_source: np.ndarray
    """``scene.receivers``, for ``receiver_boxes``."""
    hull_halfspaces: tuple[np.ndarray, np.ndarray]
    """World-space (normals, offsets) of hull(R ∪ light) (⊂ L): the light-extruded body."""
    tolerance: float = 0.0
    scale: float = 1.0
    polytope: ConvexPolytope | None = None
    """B as a polytope relative to ``origin`` (facet planes, incidence)."""
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    """The point B's ``polytope`` is expressed relative to (the camera position)."""
    visible_boundary: Brep | None = None
    """R's boundary relative to ``origin`` (see ``visible_polytope``)."""

    @property
    def visible_polytope(self) -> ConvexPolytope | None:
        """R = V ∩ S_r ∩ L as a polytope relative to ``origin``: every receiver
        box that meets V ∩ L lies in S_r, so R ∩ box = V ∩ L ∩ box."""
        if self.visible_boundary is None:
            return None
        return self._memo("_visible_polytope", lambda: ConvexPolytope.from_brep(self.visible_boundary, self.tolerance))

    @property
    def caster_mask(self) -> np.ndarray:
        """Which of ``scene.casters`` meet hull(R ∪ light) ∩ L."""
        return self._memo("_caster_mask", lambda: self.casters.mask)

    @property
    def receiver_mask(self) -> np.ndarray:
        """Which of ``scene.receivers`` meet V ∩ L."""
        return self._memo("_receiver_mask", lambda: self.receivers.mask)

    @property
    def receiver_boxes(self) -> np.ndarray:
        """World-space boxes of the receivers that meet V ∩ L (``scene.receivers[receiver_mask]``),
        e.g. for plane_optimal's default plane of interest."""
        # (np.compress copies; 4x faster than a boolean gather)
        return self._memo("_receiver_boxes", lambda: np.compress(self.receiver_mask, self.receiver_source, axis=0))

    @property
    def hull_planes(self) -> list[Plane]:
        """World-space half-spaces of hull(R ∪ light) (⊂ L)."""
        n, o = self.hull_halfspaces
        return [Plane(ni, float(oi)) for ni, oi in zip(n, o)]

    def _memo(self, name: str, make):
        value = self.__dict__.get(name)
        if value is None:
            value = self.__dict__[name] = make()
        return value

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
        """B relative to ``apex`` (e.g. a point light), for clipping in its
        frame; made once per apex, sharing B's edges."""
        if self.polytope is None:
            raise ValueError("this body has no polytope")
        apex = np.asarray(apex, dtype=np.float64)
        moved = self.__dict__.setdefault("_polytope_from", {})
        key = tuple(apex.tolist())
        if key not in moved:
            self.polytope.edges()
            moved[key] = self.polytope.translated(self.origin - apex)
        return moved[key]


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
        n_c = -(-self.count // k)
        if self.count == 0:
            self.perm = np.zeros(0, dtype=np.int64)
            b = np.zeros((1, 2, 3))
        else:
            self.perm = self._clusters(b, k)
        # Each cluster's boxes, the last padded with copies of its last box: (6, clusters, k) lo and -hi, ...
        sb = b[np.concatenate([self.perm, np.repeat(self.perm[-1:], n_c * k - self.count)])] if self.count else b[:0]
        lo, hi = sb[:, 0].reshape(n_c, k, 3), sb[:, 1].reshape(n_c, k, 3)
        self.c_box_bounds = np.ascontiguousarray(np.concatenate([lo, -hi], axis=2).transpose(2, 0, 1))   # lo, -hi
        # ... and (clusters, 6, k) centres and half extents.
        self.c_boxes = np.ascontiguousarray(_stack_of(sb).reshape(6, n_c, k).transpose(1, 0, 2))
        # The clusters' bounds, (6, clusters) lo and -hi, and (6, clusters) centres and half extents
        # (numpy reduces along a long last axis far faster than over (N, 3) rows).
        self.c_bounds = self.c_box_bounds.min(axis=2)       # (6, clusters): lo, -hi
        self.c_stack = _stack_of(np.stack([self.c_bounds[:3].T, -self.c_bounds[3:].T], axis=1))

    @staticmethod
    def _clusters(b: np.ndarray, k: int) -> np.ndarray:
        """The boxes' order by cluster: leaves of a median-split k-d tree over
        the box centres (split along the widest axis of the boxes' extent), so
        each cluster is compact. Every leaf but the last is full."""
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
        # Leaves come depth-first, left part first.
        return np.concatenate(leaves)

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
        sel = self.select(normals, offsets, tol)
        return sel.mask, sel.box

    def select(self, normals, offsets, tol: float = 0.0) -> Selection:
        """The boxes that meet the region ``normals @ x <= offsets``. A box is
        tested only against the planes that cross its cluster: a cluster wholly
        inside a half-space has every box inside it."""
        n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        o = np.asarray(offsets, dtype=np.float64).reshape(-1)
        if self.count == 0:
            return Selection(self, np.zeros(0, dtype=bool), None)
        # A plane's least and greatest value over a box: n . centre -/+ |n| . half extent.
        an = np.abs(n)
        w = np.concatenate([np.concatenate([n, -an], axis=1), np.concatenate([n, an], axis=1)])
        bounds = w @ self.c_stack - np.concatenate([o, o])[:, None]       # (2 planes, clusters)
        c_out = (bounds[: len(n)] > tol).any(axis=0)          # wholly outside some half-space
        crossing = (bounds[len(n):] > tol) & ~c_out           # not wholly inside this one
        c_in = ~(c_out | crossing.any(axis=0))                # wholly inside every half-space
        selected = np.repeat(c_in, CLUSTER_SIZE).reshape(-1, CLUSTER_SIZE)
        bounds = self.c_bounds[:, c_in]                      # (6, clusters inside): lo, then -hi
        cluster, plane = np.nonzero(crossing.T)               # (cluster, plane) pairs, by cluster
        if len(cluster):
            first = np.flatnonzero(np.concatenate([[True], cluster[1:] != cluster[:-1]]))
            edge = cluster[first]
            least = np.matmul(w[plane, None, :], self.c_boxes[cluster])[:, 0] - o[plane, None]
            hit = ~np.logical_or.reduceat(least > tol, first, axis=0)        # (edge clusters, CLUSTER_SIZE)
            selected[edge] = hit
            bounds = np.concatenate([bounds, np.where(hit, self.c_box_bounds[:, edge], np.inf).reshape(6, -1)], axis=1)
        selected = selected.ravel()[: self.count]
        if not selected.any():
            return Selection(self, selected, None)
        least = bounds.min(axis=1)
        return Selection(self, selected, np.array([least[:3], -least[3:]]))


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


class LightHull(NamedTuple):
    """hull(P ∪ light) for a convex polytope P: its half-spaces, and the
    pieces its boundary is made of (see ``light_hull``)."""

    normals: np.ndarray
    offsets: np.ndarray
    """The half-spaces ``normals @ x <= offsets``: P's facets that do not face the light, then one per
    side (each silhouette edge whose facet does not hold the light)."""
    body: Brep
    """P's boundary, whose facets and vertices the other fields refer to."""
    kept: list
    """Indices of P's facets that do not face the light."""
    sides: list | None
    """(a, c, g) per silhouette edge: P's edge a -> c in the loop of facet g, which does not face the
    light while the facet across the edge does. None when P's loops do not close."""
    holding: set
    """The kept facets whose plane holds the light (within the tolerance): their sides lie in their own
    plane, so each such facet grows over them instead of getting separate sides."""
    light: tuple
    """The light in homogeneous coordinates."""

    def brep(self, cap: tuple | None = None) -> Brep:
        """The boundary of hull(P ∪ light): P's facets that do not face the
        light and the sides, each side a triangle (a point light) or, for a sun
        (u the direction towards it), a strip along u to the plane ``cap`` =
        (m, h), m . x = h, which closes the body (m . u > 0, and P strictly on
        the side m . x < h: B uses the face of S_c the light leaves it by, so
        S_c's own clip has one plane less to cut). A facet holding the light
        takes its sides into its own loop (its run of silhouette edges a1 ...
        ak becomes a1, light, ak, or a1, a1', ak', ak for a sun), so no two
        facets share a plane. P itself when no facet faces the light (a point
        light inside or on P)."""
        b = self.body
        if self.sides is None:
            raise OpenCut("P's loops do not close: the hull has no boundary")
        if not self.sides:
            return b
        x, y, z, w = self.light
        sun = w == 0
        apex = -1                                  # ids < 0: the light, and -2 - v for v raised to the cap
        silhouette = {(a, c) for a, c, _ in self.sides}
        normals = [b.normals[g] for g in self.kept]
        offsets = [b.offsets[g] for g in self.kept]
        loops, cap_next = [], {}
        for g in self.kept:
            loop = b.loops[g]
            if g not in self.holding:
                loops.append(list(loop))
                continue
            k = len(loop)
            on = [(loop[i - 1], loop[i]) in silhouette for i in range(k)]     # edge into loop[i]
            starts = [i for i in range(k) if on[i] and not on[i - 1]]
            if not any(on):
                loops.append(list(loop))
                continue
            if len(starts) != 1:
                raise OpenCut("a facet holding the light sees it across more than one run of edges")
            i = starts[0] - 1                      # the run is loop[i] -> ... -> loop[j]
            j = i + 1
            while on[(j + 1) % k]:
                j += 1
            first, last = loop[i % k], loop[j % k]
            grown = [first, -2 - first, -2 - last, last] if sun else [first, apex, last]
            grown += [loop[(j + 1 + t) % k] for t in range(k - (j - i) - 1)]
            loops.append(grown)
            if sun:
                cap_next[-2 - last] = -2 - first
        rows = iter(zip(self.normals[len(self.kept):].tolist(), self.offsets[len(self.kept):].tolist()))
        for a, c, g in self.sides:
            if g in self.holding:
                continue
            n, o = next(rows)
            normals.append(tuple(n))
            offsets.append(o)
            if sun:
                loops.append([c, a, -2 - a, -2 - c])
                cap_next[-2 - c] = -2 - a
            else:
                loops.append([c, a, apex])
        if sun:
            (mx, my, mz), h = cap
            start = min(cap_next)
            ring, v = [start], cap_next[start]
            while v != start and len(ring) <= len(cap_next):
                ring.append(v)
                v = cap_next.get(v, start)
            if len(ring) != len(cap_next) or v != start:
                raise OpenCut("the silhouette is not one loop")
            normals.append((mx, my, mz))
            offsets.append(h)
            loops.append(ring)
            rate = mx * x + my * y + mz * z
        # Number the vertices the loops use: P's, then the light or the raised ones.
        index, verts = {}, []
        for loop in loops:
            for v in loop:
                if v in index:
                    continue
                index[v] = len(verts)
                if v >= 0:
                    verts.append(b.vertices[v])
                elif v == apex:
                    verts.append((x / w, y / w, z / w))
                else:                              # v moved along u onto the cap plane
                    px, py, pz = b.vertices[-2 - v]
                    t = (h - (mx * px + my * py + mz * pz)) / rate
                    verts.append((px + t * x, py + t * y, pz + t * z))
        return Brep(verts, normals, offsets, [[index[v] for v in loop] for loop in loops])


def light_hull(b: Brep, light_h, tol: float) -> LightHull:
    """hull(P ∪ light) for a convex polyhedron P (its boundary ``b``), the
    light in homogeneous coordinates (x, y, z, w), w = 0 for a light at
    infinity (then (x, y, z) is the unit direction towards it).

    Its half-spaces are P's facets that do not face the light plus, through
    each silhouette edge (a facet g that does not face the light next to one, f,
    that does), the plane through that edge and the light. With F(x) = n_f . x - o_f
    and G likewise, that plane is the positive combination

        σ = -G(light) · F + F(light) · G,     σ(light) = 0,

    of two half-spaces that hold P, so it holds P exactly, however short the
    edge (no cross product of its endpoints); any such σ holds hull(P ∪ light).
    A facet within the tolerance of the light counts as not facing it, and
    holds it: its σ is its own plane, so it adds none. When P's loops do not
    close (a near-degenerate clip), facets sharing two vertices count as
    neighbours and the hull has half-spaces but no boundary (``LightHull.sides``
    is None)."""
    x, y, z, w = (float(c) for c in light_h)
    s = [nx * x + ny * y + nz * z - o * w for (nx, ny, nz), o in zip(b.normals, b.offsets)]
    threshold = tol if w != 0 else SUN_FACING
    facing = [v > threshold for v in s]
    kept = [g for g in range(len(b.loops)) if not facing[g]]
    holding = {g for g in kept if s[g] >= -threshold}
    owner = directed_edges(b.loops)
    pairs, sides = [], []
    for g in kept:
        loop = b.loops[g]
        for i in range(len(loop)):
            a, c = loop[i - 1], loop[i]
            f = owner.get((c, a))
            if f is None:
                sides = None
                break
            if facing[f]:
                sides.append((a, c, g))
                if g not in holding:
                    pairs.append((f, g))
        if sides is None:
            break
    if sides is None:
        loops = [set(loop) for loop in b.loops]
        pairs = [(f, g) for g in kept if g not in holding
                 for f in range(len(b.loops)) if facing[f] and len(loops[f] & loops[g]) >= 2]
    normals = [b.normals[g] for g in kept]
    offsets = [b.offsets[g] for g in kept]
    for f, g in pairs:
        wf, wg = -s[g], s[f]
        (fx, fy, fz), (gx, gy, gz) = b.normals[f], b.normals[g]
        nx, ny, nz = wf * fx + wg * gx, wf * fy + wg * gy, wf * fz + wg * gz
        length = math.sqrt(nx * nx + ny * ny + nz * nz)
        if length == 0.0:               # f and g opposite: P is flat there, and g alone bounds it
            nx, ny, nz, length, wf, wg = gx, gy, gz, 1.0, 0.0, 1.0
        normals.append((nx / length, ny / length, nz / length))
        offsets.append((wf * b.offsets[f] + wg * b.offsets[g]) / length)
    return LightHull(np.array(normals, dtype=np.float64).reshape(-1, 3), np.array(offsets, dtype=np.float64),
                     b, kept, sides, holding, (x, y, z, w))


_BOX_NORMALS = np.concatenate([-np.eye(3), np.eye(3)])
"""Outward normals of a box's facets -x, -y, -z, +x, +y, +z (offsets: -lo, hi)."""
_BOX_NORMALS_LIST = _BOX_NORMALS.tolist()


def _box_offsets(box, pad: float) -> list[float]:
    """The offsets of the facets -x, -y, -z, +x, +y, +z (``_BOX_NORMALS``) of
    the box [lo, hi] widened by ``pad``."""
    return [pad - c for c in box[0]] + [c + pad for c in box[1]]


def intersection_body(view: View, light: Light, scene: SceneBounds) -> IntersectionBody:
    """B for this view, light and scene (Scherzer §4.1). Raises EmptyBodyError
    (with the reason) when nothing visible can receive a shadow."""
    if scene.is_empty:
        raise EmptyBodyError("the scene has no shadow casters or receivers")
    origin = view.position
    corners = view.corners() - origin
    view_size = math.dist(corners[0], corners[7])
    try:
        frustum = brep.hexahedron(corners)
    except OpenCut:
        frustum = ConvexPolytope.from_corners(corners, RELATIVE_TOLERANCE * view_size).brep()
    ln, lo = light_halfspaces(light, origin)
    cone = " and the spot cone" if len(ln) else ""
    if len(ln):
        # Only the cone's planes that cut V matter for V ∩ L (V is convex).
        d = ln @ corners.T - lo[:, None]
        if np.any(d.min(axis=1) >= 0):
            raise EmptyBodyError("no shadow receiver is lit in view: the view frustum is outside the spot cone")
        cuts = d.max(axis=1) > 0
        ln, lo = ln[cuts], lo[cuts]

    # Receivers meeting V ∩ L (planes moved to world space for the culling).
    vn = np.concatenate([frustum.normals, ln])
    vo = np.concatenate([frustum.offsets, lo])
    receivers = BoxIndex.of(scene, "receivers").select(vn, vo + vn @ origin)
    if receivers.box is None:
        raise EmptyBodyError("no shadow receiver is inside the view frustum" + cone)
    s_r = (receivers.box - origin).tolist()
    scale = max(math.dist(*s_r), view_size * 1e-6, 1e-9)
    tol = RELATIVE_TOLERANCE * max(scale, max(abs(c) for corner in s_r for c in corner))

    # R = V ∩ S_r ∩ L.
    planes_n = _BOX_NORMALS_LIST + ln.tolist()
    planes_o = _box_offsets(s_r, max(BOX_PAD * scale, 512 * tol)) + lo.tolist()
    try:
        visible = brep.clip(frustum, planes_n, planes_o, tol)
    except OpenCut:
        poly = ConvexPolytope.from_corners(corners, tol).clip(np.array(planes_n), np.array(planes_o))
        visible = None if poly is None else poly.brep()
    if visible is None:
        raise EmptyBodyError("the view frustum does not meet the receivers" + (" inside the spot cone" if len(ln) else ""))

    # hull(R ∪ light) ∩ L, and the casters meeting it.
    light_h = light.homogeneous_position.copy()
    if light_h[3] != 0:
        light_h[:3] -= origin
    # hull(R ∪ light) ⊂ L already (L is a convex cone with its apex at the light and R ⊂ L),
    # so L's planes would only repeat what the hull says.
    hull = light_hull(visible, light_h, tol)
    hn, ho = hull.normals, hull.offsets + hull.normals @ origin
    casters = BoxIndex.of(scene, "casters").select(hull.normals, ho, tol)
    axes = list(zip(*visible.vertices))
    s_c = [[min(c) for c in axes], [max(c) for c in axes]]
    if casters.box is not None:
        lo_c, hi_c = (casters.box - origin).tolist()
        s_c = [[min(a, b) for a, b in zip(s_c[0], lo_c)], [max(a, b) for a, b in zip(s_c[1], hi_c)]]
    scale = max(math.dist(*s_c), scale)
    box_o = _box_offsets(s_c, max(BOX_PAD * scale, 512 * tol))

    # B = hull(R ∪ light) ∩ S_c; a sun's hull is closed on the face of S_c the light leaves it by.
    try:
        cap = None
        if light_h[3] == 0:
            exit_face = int(np.argmax(_BOX_NORMALS @ light_h[:3]))
            cap = (_BOX_NORMALS_LIST[exit_face], box_o[exit_face])
        body = brep.clip(hull.brep(cap), _BOX_NORMALS_LIST, box_o, tol)
        body = None if body is None else ConvexPolytope.from_brep(body, tol)
    except OpenCut:
        body = ConvexPolytope.box(-np.array(box_o[:3]), np.array(box_o[3:]), tol).clip(hull.normals, hull.offsets)
    if body is None:
        raise EmptyBodyError("the light-extruded view does not meet the scene")
    visible_vertices = np.array(visible.vertices, dtype=np.float64)
    return IntersectionBody(
        vertices=body.vertices + origin,
        faces=LazyFaces(body, origin),
        visible_vertices=visible_vertices + origin,
        casters=casters,
        receivers=receivers,
        receiver_source=scene.receivers,
        hull_halfspaces=(hn, ho),
        tolerance=tol,
        scale=scale,
        polytope=body,
        origin=origin,
        visible_boundary=visible,
    )
