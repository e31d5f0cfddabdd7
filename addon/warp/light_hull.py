"""What a light adds to a body: its frustum L (the spot cone as a circumscribed pyramid; all space otherwise) and
hull(P ∪ light), which holds everything that can shadow P (Scherzer §4.1, Fig. 5), the light homogeneous."""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .geometry import cross, normalize, perpendicular
from .polyhedron import ConvexPolytope, OpenCut, closed_loop
from .types import Light

CONE_SIDES = 16
"""The spot cone is bounded by a circumscribed pyramid with this many sides."""

SUN_FACING = 1e-12
"""A facet faces a sun when cos(angle to the direction towards it) exceeds this."""

_CONE_ANGLES = 2 * math.pi * np.arange(CONE_SIDES) / CONE_SIDES
_CONE_ROWS = np.stack([np.cos(_CONE_ANGLES), np.sin(_CONE_ANGLES), np.ones(CONE_SIDES)], axis=1)
"""(cos θ_i, sin θ_i, 1) per side of the pyramid."""


def light_halfspaces(light: Light, origin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """L relative to ``origin``: (normals (k, 3), offsets (k,)) of a spot's CONE_SIDES pyramid (k = 0 otherwise)."""
    if light.type != "SPOT":
        return np.zeros((0, 3)), np.zeros(0)
    a = normalize(light.direction)
    u, widened = pyramid_side(a), math.atan(math.tan(light.spot_angle / 2) / math.cos(math.pi / CONE_SIDES))
    c, s = math.cos(widened), math.sin(widened)
    normals = _CONE_ROWS @ np.array([c * u, c * cross(a, u), -s * a])
    return normals, normals @ (light.position - origin)


def pyramid_side(a) -> np.ndarray:
    """The pyramid's first side direction: world x turned by the least rotation from straight down to the unit axis
    ``a`` (Rodrigues), so it turns continuously with the spot; singular only pointing straight up."""
    (ax, ay, az), k = a.tolist(), 1.0 - float(a[2])
    return perpendicular(a) if k < 1e-9 else normalize(np.array([1.0 - ax * ax / k, -ax * ay / k, ax]))


class Side(NamedTuple):
    """A silhouette edge a -> c of P, in the loop of facet ``kept`` (not facing the
    light) across from facet ``facing`` (facing it)."""

    a: int
    c: int
    kept: int
    facing: int


class LightHull(NamedTuple):
    """hull(P ∪ light) for a convex polytope P (see ``light_hull``)."""

    normals: np.ndarray
    offsets: np.ndarray
    """The half-spaces ``normals @ x <= offsets``: P's facets that do not face the light, then one per
    silhouette edge whose facet does not hold the light."""
    body: ConvexPolytope
    """P."""
    kept: list
    """P's facets that do not face the light."""
    sides: list | None
    """The silhouette edges (``Side``); None when P's loops do not close."""
    holding: set
    """The kept facets whose plane holds the light (within the tolerance): their sides lie in their own
    plane, so each such facet grows over them instead of getting separate sides."""
    light: np.ndarray
    """The light in homogeneous coordinates."""

    def polytope(self, cap: tuple | None = None) -> ConvexPolytope:
        """hull(P ∪ light) as a polytope: P's facets not facing the light and the sides (triangles to a point light;
        for a sun, strips up to the plane ``cap`` = (m, h)). P itself when no facet faces the light."""
        p = self.body
        if self.sides is None:
            raise OpenCut("P's loops do not close: the hull has no boundary")
        if not self.sides:
            return p
        n, sun = len(p.vertices), self.light[3] == 0
        # Vertex ids: P's, then n + v for P's vertex v raised to the cap (a sun) or n for the light.
        silhouette = {(s.a, s.c) for s in self.sides}
        ring: dict = {}                  # a sun's cap edges (raised vertex -> next), from the sides and grown facets
        loops = [_grow_over_sides(p.loops[g], silhouette, n, sun, ring) if g in self.holding else p.loops[g]
                 for g in self.kept]
        for s in self.sides:
            if s.kept not in self.holding:
                loops.append([s.c, s.a, n + s.a, n + s.c] if sun else [s.c, s.a, n])
                if sun:
                    ring[n + s.c] = n + s.a
        normals, offsets, vertices = self.normals, self.offsets, [p.vertices]
        if sun:
            m, h = np.asarray(cap[0], dtype=np.float64), cap[1]
            loops.append(closed_loop(ring))
            normals, offsets = np.concatenate([normals, [m]]), np.concatenate([offsets, [h]])
            u = self.light[:3]
            vertices.append(p.vertices + ((h - p.vertices @ m) / (m @ u))[:, None] * u)
        else:
            vertices.append(self.light[None, :3] / self.light[3])
        used = sorted({v for loop in loops for v in loop})
        index = {v: i for i, v in enumerate(used)}
        return ConvexPolytope(np.concatenate(vertices)[used], normals, offsets,
                              tuple([index[v] for v in loop] for loop in loops), p.tol)


def _grow_over_sides(loop, silhouette: set, n: int, sun: bool, ring: dict) -> list:
    """A facet's loop holding the light, its one run of silhouette edges a1 .. ak
    replaced by a1, light, ak (a sun: a1, a1', ak', ak, the cap edge into ``ring``)."""
    k = len(loop)
    on = [(loop[i - 1], loop[i]) in silhouette for i in range(k)]       # the edge into loop[i]
    starts = [i for i in range(k) if on[i] and not on[i - 1]]
    if not any(on):
        return loop
    if len(starts) != 1:
        raise OpenCut("a facet holding the light sees it across more than one run of edges")
    i = starts[0] - 1                                                   # the run is loop[i] -> ... -> loop[j]
    j = i + 1
    while on[(j + 1) % k]:
        j += 1
    first, last = loop[i % k], loop[j % k]
    grown = [first, n + first, n + last, last] if sun else [first, n, last]
    if sun:
        ring[n + last] = n + first
    return grown + [loop[(j + 1 + t) % k] for t in range(k - (j - i) - 1)]


def light_hull(p: ConvexPolytope, light_h) -> LightHull:
    """hull(P ∪ light) as half-spaces (Scherzer §4.1), the light homogeneous (w = 0: the unit direction towards
    it): P's facets not facing the light and, through each silhouette edge between g (not facing) and f (facing),
    σ = -G(light)·F + F(light)·G. Open loops (a near-degenerate clip): half-spaces but no sides."""
    light = np.asarray(light_h, dtype=np.float64)
    planes = np.concatenate([p.normals, -p.offsets[:, None]], axis=1)  # F(X) = plane · X for X = (x, 1)
    s = planes @ light                                                # F(light) of every facet
    threshold = p.tol if light[3] != 0 else SUN_FACING
    facing = (s > threshold).tolist()
    kept = [g for g, f in enumerate(facing) if not f]
    holding = {g for g, near in enumerate((s >= -threshold).tolist()) if near and not facing[g]}
    sides = _silhouette(p.loops, kept, facing)
    if sides is not None:
        pairs = [(side.facing, side.kept) for side in sides if side.kept not in holding]
    else:
        loops = [set(loop) for loop in p.loops]
        pairs = [(f, g) for g in kept if g not in holding
                 for f in range(len(p.loops)) if facing[f] and len(loops[f] & loops[g]) >= 2]
    f, g = np.array(pairs, dtype=np.int64).reshape(-1, 2).T
    sigma = s[f, None] * planes[g] - s[g, None] * planes[f]
    length = np.sqrt(np.einsum("ij,ij->i", sigma[:, :3], sigma[:, :3]))
    if not length.all():                      # f and g opposite: P is flat there, and g alone bounds it
        flat = length == 0.0
        sigma[flat], length[flat] = planes[g[flat]], 1.0
    hull = np.concatenate([planes[kept], sigma / length[:, None]])
    return LightHull(hull[:, :3], -hull[:, 3], p, kept, sides, holding, light)


def _silhouette(loops, kept: list, facing: list) -> list | None:
    """The edges of kept facets whose facet across faces the light; None when an edge has none across (open loops)."""
    across = {}                                      # edge (a, c) -> the facet whose loop runs c -> a
    for f, loop in enumerate(loops):
        a = loop[-1]
        for c in loop:
            across[c, a] = f
            a = c
    sides = []
    for g in kept:
        loop = loops[g]
        a = loop[-1]
        for c in loop:
            f = across.get((a, c))
            if f is None:
                return None
            if facing[f]:
                sides.append(Side(a, c, g, f))
            a = c
    return sides
