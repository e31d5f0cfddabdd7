"""The intersection body B = hull(R ∪ light) ∩ S_c, R = V ∩ S_r ∩ L (Scherzer §4.1, Fig. 5;
Stamminger-Drettakis §4.1), as convex polytopes relative to the camera position (docs/papers.md)."""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .culling import BoxIndex, Selection
from .light_hull import light_halfspaces, light_hull
from .polyhedron import BOX_NORMALS, ConvexPolytope, OpenCut, box_offsets, unit_halfspaces
from .types import EmptyBodyError, Light, SceneBounds, View
from .visibility import VisibleRegion

log = logging.getLogger(__name__)

RELATIVE_TOLERANCE = 1e-10
BOX_PAD = 1e-7
"""Boxes are padded by this fraction of B's scale (and at least 512 tolerances) so a flat scene, or a single
point-sized box, still gives a closed body at least 1000 tolerances thick."""


@dataclass(frozen=True)
class Culled:
    """The culling result: the scene's boxes B was built from."""

    receivers: Selection
    """The receivers that meet V ∩ L."""
    casters: Selection
    """The casters that meet hull(R ∪ light) (⊂ L): they can shadow what is seen."""


@dataclass(frozen=True, eq=False)
class IntersectionBody:
    """B relative to ``origin`` (the camera position), with R and the culling it was built from."""

    polytope: ConvexPolytope
    """B = hull(R ∪ light) ∩ S_c."""
    visible_polytope: ConvexPolytope
    """R = V ∩ S_r ∩ L: the part of the view that holds receivers."""
    origin: np.ndarray
    scale: float
    """A length typical of B: S_c's diagonal as far as it can be seen or shadow what is (tolerances, padding)."""
    hull_halfspaces: tuple[np.ndarray, np.ndarray]
    """World-space (normals, offsets) of hull(R ∪ light) (⊂ L): the light-extruded view."""
    culled: Culled
    visible: VisibleRegion | None = None
    """The visible region (:mod:`.visibility`) R was focused on; None: R spans the view frustum."""
    cube_axis: np.ndarray | None = None
    """A light's cube axis on B (``frame.point_frames``; None: B's cone axis): a cascade's splits take the whole B's."""

    @property
    def focus(self) -> str:
        """What R was fitted to: the visible region's source, or "view frustum"."""
        return "view frustum" if self.visible is None else self.visible.source

    @property
    def tolerance(self) -> float:
        return self.polytope.tol

    @cached_property
    def vertices(self) -> np.ndarray:
        """B's vertices in world space."""
        return self.polytope.vertices + self.origin

    @cached_property
    def faces(self) -> list[np.ndarray]:
        """B's faces as world-space vertex loops, counter-clockwise seen from outside."""
        return [f + self.origin for f in self.polytope.faces()]

    @cached_property
    def visible_vertices(self) -> np.ndarray:
        """R's vertices in world space."""
        return self.visible_polytope.vertices + self.origin

    @cached_property
    def centroid(self) -> np.ndarray:
        """The mean of B's vertices (the axis a point light's angles are measured along)."""
        return self.polytope.centroid + self.origin

    @cached_property
    def volume_centroid(self) -> np.ndarray:
        """The centre of B's volume (B's middle, Scherzer §4.4), world space."""
        return self.polytope.volume_centroid + self.origin

    def contains(self, points, tol: float | None = None) -> np.ndarray:
        """Which (N, 3) world points lie in B (within ``tol``, default 10x the tolerance)."""
        return self.polytope.contains(np.asarray(points, dtype=np.float64).reshape(-1, 3) - self.origin, tol)

    def polytope_from(self, apex) -> ConvexPolytope:
        """B relative to ``apex`` (e.g. a point light, or the camera), made once per apex."""
        key = tuple(np.asarray(apex, dtype=np.float64).tolist())
        if key == tuple(self.origin.tolist()):
            return self.polytope
        moved = self.__dict__.setdefault("_moved", {})
        if key not in moved:
            moved[key] = self.polytope.translated(self.origin - np.array(key))
        return moved[key]


def view_frustum(view: View, origin: np.ndarray) -> ConvexPolytope:
    """V relative to ``origin``, its tolerance relative to its size."""
    corners = view.corners() - origin
    return ConvexPolytope.hexahedron(corners, RELATIVE_TOLERANCE * math.dist(corners[0], corners[7]))


def intersection_body(view: View, light: Light, scene: SceneBounds,
                      visible: VisibleRegion | None = None, least: float = 0.0) -> IntersectionBody:
    """B for this view, light and scene (Scherzer §4.1), R cut by ``visible`` when given, its scale at least ``least``
    (a cascade's splits take the whole B's); EmptyBodyError, with the reason, when nothing visible can be shadowed."""
    if scene.is_empty:
        raise EmptyBodyError("the scene has no shadow casters or receivers")
    origin = view.position
    frustum = view_frustum(view, origin)
    corners = frustum.vertices
    view_size = math.dist(corners[0], corners[7])
    if visible is not None:
        n, o = visible.halfspaces(view, light)
        frustum = frustum.clip(*unit_halfspaces(n, o - n @ origin))
        if frustum is None:
            raise EmptyBodyError(f"the visible region ({visible.source}) does not meet the view frustum")
    ln, lo = light_halfspaces(light, origin)
    cone = " and the spot cone" if len(ln) else ""
    # Only the cone's planes that cut V matter for V ∩ L (V is convex).
    d = ln @ corners.T - lo[:, None]
    if np.any(d.min(axis=1) >= 0):
        raise EmptyBodyError("no shadow receiver is lit in view: the view frustum is outside the spot cone")
    cuts = d.max(axis=1) > 0
    ln, lo = ln[cuts], lo[cuts]

    # Receivers meeting V ∩ L (planes moved to world space for the culling).
    vn, vo = np.concatenate([frustum.normals, ln]), np.concatenate([frustum.offsets, lo])
    receivers = BoxIndex.of(scene, "receivers").select(vn, vo + vn @ origin)
    if receivers.box is None:
        raise EmptyBodyError("no shadow receiver is inside the view frustum" + cone)
    s_r, seen = receivers.box - origin, frustum.vertices      # S_r as far as V sees (inside out: V misses it)
    s_r = np.array([np.maximum(s_r[0], seen.min(axis=0)), np.minimum(s_r[1], seen.max(axis=0))])
    scale = max(math.dist(*s_r), view_size * 1e-6, 1e-9, least)
    tol = RELATIVE_TOLERANCE * max(scale, float(np.abs(s_r).max()))

    # R = V ∩ S_r ∩ L.
    pad = max(BOX_PAD * scale, 512 * tol)
    bn, bo = np.concatenate([BOX_NORMALS, ln]), np.concatenate([box_offsets(*s_r) + pad, lo])     # S_r, padded; L
    r = ConvexPolytope(frustum.vertices, frustum.normals, frustum.offsets, frustum.loops, tol).clip(bn, bo)
    if r is None:
        raise EmptyBodyError("the view frustum does not meet the receivers" + (" inside the spot cone" if len(ln) else ""))

    # hull(R ∪ light) ⊂ L already (L is a convex cone with its apex at the light and R ⊂ L),
    # so L's planes would only repeat what the hull says; the casters meeting it.
    light_h = np.array(light.homogeneous_from(origin))
    hull = light_hull(r, light_h)
    casters = BoxIndex.of(scene, "casters").select(hull.normals, hull.offsets + hull.normals @ origin, tol)
    held = r.vertices if casters.box is None else np.concatenate([r.vertices, casters.box - origin])
    s_c = np.clip([held.min(axis=0), held.max(axis=0)], *_reach(r.vertices, light_h, held))
    scale = max(math.dist(*s_c), scale)
    pad = max(BOX_PAD * scale, 512 * tol)
    bn, bo = BOX_NORMALS, box_offsets(*s_c) + pad

    # B = hull(R ∪ light) ∩ S_c; a sun's hull is closed on the face of S_c the light leaves it by.
    try:
        exit_face = int(np.argmax(bn @ light_h[:3]))
        body = hull.polytope((bn[exit_face], bo[exit_face]) if light_h[3] == 0 else None).clip(bn, bo)
    except OpenCut as why:
        log.debug("B by vertex enumeration: %s", why)
        body = ConvexPolytope.box(s_c[0] - pad, s_c[1] + pad, tol).clip(hull.normals, hull.offsets)
    if body is None:
        raise EmptyBodyError("the light-extruded view does not meet the scene")
    return IntersectionBody(body, r, origin, scale, (hull.normals, hull.offsets + hull.normals @ origin),
                            Culled(receivers, casters), visible)


def _reach(r: np.ndarray, light_h: np.ndarray, held: np.ndarray) -> np.ndarray:
    """A (2, 3) box holding hull(R ∪ light) ∩ bbox(``held``): R's box and the light, or for a sun R's box swept towards
    it until it leaves ``held``'s box (the least exit distance over the axes' slabs): what can shadow R."""
    box, d = np.array([r.min(axis=0), r.max(axis=0)]), light_h[:3]
    if light_h[3]:
        return np.array([np.minimum(box[0], d), np.maximum(box[1], d)])
    exits = np.where(d > 0, held.max(axis=0) - box[0], held.min(axis=0) - box[1])
    t = max(0.0, min(float(e / di) for e, di in zip(exits, d) if abs(di) > 1e-12))
    return box + np.array([np.minimum(0.0, t * d), np.maximum(0.0, t * d)])
