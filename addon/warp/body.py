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
culled through a two-level index (:mod:`.culling`), and L and the light hull
come from :mod:`.light_hull`.

Cost on a 10,000-box scene (``make bench``): see docs/performance.md.
"""
from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from . import brep
from .brep import Brep, OpenCut
from .culling import BoxIndex, Selection
from .light_hull import light_halfspaces, light_hull
from .polyhedron import ConvexPolytope, Plane, float_rows
from .types import EmptyBodyError, Light, SceneBounds, View
from .visibility import VisibleRegion

log = logging.getLogger(__name__)

RELATIVE_TOLERANCE = 1e-10
BOX_PAD = 1e-7
"""Boxes are padded by this fraction of the scene scale (and at least 512
tolerances) so a flat scene, or a single point-sized box, still gives a closed
body at least 1000 tolerances thick."""


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
    visible: VisibleRegion | None = None
    """The visible region R was focused on (None: R spans the view frustum)."""

    @property
    def focus(self) -> str:
        """What R was fitted to: the visible region's source, or "view frustum"."""
        return "view frustum" if self.visible is None else self.visible.source

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
        """The mean of B's vertices (the axis a point light's angles are measured along)."""
        return self._memo("_centroid", lambda: self.vertices.sum(axis=0) / len(self.vertices))

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


_BOX_NORMALS = np.concatenate([-np.eye(3), np.eye(3)])
"""Outward normals of a box's facets -x, -y, -z, +x, +y, +z (offsets: -lo, hi)."""
_BOX_NORMALS_LIST = _BOX_NORMALS.tolist()


def _box_offsets(box, pad: float) -> list[float]:
    """The offsets of the facets -x, -y, -z, +x, +y, +z (``_BOX_NORMALS``) of
    the box [lo, hi] widened by ``pad``."""
    return [pad - c for c in box[0]] + [c + pad for c in box[1]]


def _clip_to_box(b: Brep, box_o: list[float], tol: float) -> Brep | None:
    """``b`` ∩ the box whose facets -x, -y, -z, +x, +y, +z (``_BOX_NORMALS``)
    have the offsets ``box_o``, as ``brep.clip`` by its six planes gives it,
    cutting only by the facets ``b`` reaches beyond: a box facet's greatest
    distance over ``b``'s vertices is that of their bounding box, exactly the
    test ``brep.cut`` starts with (-x - o and x - o, the other terms zero), and
    a facet ``b`` does not reach beyond cuts nothing after the others either
    (their cuts' new vertices lie on ``b``'s edges)."""
    axes = list(zip(*b.vertices))
    reach = [-min(c) for c in axes] + [max(c) for c in axes]
    cuts = [i for i in range(6) if reach[i] - box_o[i] > tol]
    return brep.clip(b, [_BOX_NORMALS_LIST[i] for i in cuts], [box_o[i] for i in cuts], tol)


def _focused(frustum: Brep, corners: np.ndarray, focus: tuple[list, list], tol: float) -> Brep | None:
    """V cut by the visible region's half-spaces ``focus`` (camera-relative, like V)."""
    try:
        return brep.clip(frustum, *focus, tol)
    except OpenCut as why:
        log.debug("focused V by vertex enumeration: %s", why)
        poly = ConvexPolytope.from_corners(corners, tol).clip(np.array(focus[0]), np.array(focus[1]))
        return None if poly is None else poly.brep()


def intersection_body(view: View, light: Light, scene: SceneBounds,
                      visible: VisibleRegion | None = None) -> IntersectionBody:
    """B for this view, light and scene (Scherzer §4.1). Raises EmptyBodyError
    (with the reason) when nothing visible can receive a shadow.

    ``visible`` focuses B on what the camera sees (:mod:`.visibility`): V is
    cut by the region's half-spaces first, so R holds the visible points only
    while B = hull(R ∪ light) ∩ S_c still holds every caster that can shadow
    one of them."""
    if scene.is_empty:
        raise EmptyBodyError("the scene has no shadow casters or receivers")
    origin = view.position
    corners = view.corners() - origin
    view_size = math.dist(corners[0], corners[7])
    try:
        frustum = brep.hexahedron(corners.tolist())         # (plain floats: float() on numpy scalars is slow)
    except OpenCut as why:
        log.debug("view frustum by vertex enumeration: %s", why)
        frustum = ConvexPolytope.from_corners(corners, RELATIVE_TOLERANCE * view_size).brep()
    focus: tuple[list, list] = ([], [])
    if visible is not None:
        n, o = visible.halfspaces(view, light)
        focus = (n.tolist(), (o - n @ origin).tolist())
        frustum = _focused(frustum, corners, focus, RELATIVE_TOLERANCE * view_size)
        if frustum is None:
            raise EmptyBodyError(f"the visible region ({visible.source}) does not meet the view frustum")
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
        visible_r = brep.clip(frustum, planes_n, planes_o, tol)
    except OpenCut as why:
        log.debug("R by vertex enumeration: %s", why)
        poly = ConvexPolytope.from_corners(corners, tol).clip(np.array(planes_n + focus[0]),
                                                              np.array(planes_o + focus[1]))
        visible_r = None if poly is None else poly.brep()
    if visible_r is None:
        raise EmptyBodyError("the view frustum does not meet the receivers" + (" inside the spot cone" if len(ln) else ""))

    # hull(R ∪ light) ∩ L, and the casters meeting it.
    light_h = light.homogeneous_from(origin)
    # hull(R ∪ light) ⊂ L already (L is a convex cone with its apex at the light and R ⊂ L),
    # so L's planes would only repeat what the hull says.
    hull = light_hull(visible_r, light_h, tol)
    hn, ho = hull.normals, hull.offsets + hull.normals @ origin
    casters = BoxIndex.of(scene, "casters").select(hull.normals, ho, tol)
    axes = list(zip(*visible_r.vertices))
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
            rate = [-light_h[0], -light_h[1], -light_h[2], *light_h[:3]]      # along _BOX_NORMALS
            exit_face = rate.index(max(rate))
            cap = (_BOX_NORMALS_LIST[exit_face], box_o[exit_face])
        body = _clip_to_box(hull.brep(cap), box_o, tol)
        body = None if body is None else ConvexPolytope.from_brep(body, tol)
    except OpenCut as why:
        log.debug("B by vertex enumeration: %s", why)
        body = ConvexPolytope.box(-np.array(box_o[:3]), np.array(box_o[3:]), tol).clip(hull.normals, hull.offsets)
    if body is None:
        raise EmptyBodyError("the light-extruded view does not meet the scene")
    visible_vertices = float_rows(visible_r.vertices)
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
        visible_boundary=visible_r,
        visible=visible,
    )
