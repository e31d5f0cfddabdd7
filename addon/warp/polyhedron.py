"""Convex polytopes: the one representation of every convex body in the warp core (V, R, the light hull, B),
float64, tolerances passed in, deterministic; its clip (a face walk) and section (Cyrus-Beck): docs/papers.md."""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from itertools import chain, combinations
from typing import NamedTuple

import numpy as np

from .geometry import UNIT_CUBE_CORNERS, cross

EPS = float(np.finfo(np.float64).eps)

SNAP = 4.0
"""Vertices closer than SNAP tolerances are one vertex, and a vertex within SNAP tolerances of a plane lies on it: one
scale for both, so near-degenerate corners (a plane passing a vertex at a few tolerances) give consistent faces."""

COINCIDENT = 1000.0
"""Facet planes whose signed distances differ by less than this many tolerances
at every vertex are one facet (B is padded to at least this thickness)."""

DET_MIN = 1e-13
"""Triples of planes whose normals' triple product is below this are treated as
meeting in no single point (parallel or sharing a line)."""

HEXAHEDRON_LOOPS = ((0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5))
"""The six quads of a hexahedron whose corners are ordered like ``geometry.UNIT_CUBE_CORNERS`` (near face first, x
fastest, then y): near, far, bottom, top, left, right, counter-clockwise seen from outside for a box."""

HEXAHEDRON_EDGES = np.array([(loop[i - 1], loop[i]) for loop in HEXAHEDRON_LOOPS[:2] for i in range(4)]
                            + [(i, i + 4) for i in range(4)])
"""The 12 edges of such a hexahedron as pairs of corners: the near and far loops', then near to far."""

BOX_NORMALS = np.concatenate([-np.eye(3), np.eye(3)])
"""The outward normals of a box's facets -x, -y, -z, +x, +y, +z (offsets -lo, hi: ``box_offsets``)."""

BOX_LOOPS = tuple(HEXAHEDRON_LOOPS[i] for i in (4, 2, 0, 5, 3, 1))
"""The ``HEXAHEDRON_LOOPS`` of a box's facets in ``BOX_NORMALS`` order."""


def box_corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The corners (..., 8, 3) of boxes [lo, hi] (``geometry.UNIT_CUBE_CORNERS`` order)."""
    return np.where(UNIT_CUBE_CORNERS > 0, hi[..., None, :], lo[..., None, :]) + 0.0


def box_offsets(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The offsets (..., 6) of the facets ``BOX_NORMALS`` of boxes [lo, hi]: -lo, hi."""
    return np.concatenate([-lo, hi], axis=-1)


def box_edges(lo: np.ndarray, hi: np.ndarray) -> "Edges":
    """The 12 edges of boxes [lo, hi] ((..., 3) each) as segments (..., 12)."""
    corners = box_corners(lo, hi)
    start, end = corners[..., HEXAHEDRON_EDGES[:, 0], :], corners[..., HEXAHEDRON_EDGES[:, 1], :]
    return Edges(start, end - start, np.ones(start.shape[:-1]))


class OpenCut(ValueError):
    """A cut whose new boundary does not close into one loop (the clip falls back to vertex enumeration)."""


@dataclass(frozen=True, eq=False)
class ConvexPolytope:
    """A closed convex polytope: ``vertices`` (n, 3); per facet its unit outward normal, offset and vertex loop
    (CCW seen from outside); ``tol``, the length below which points and planes meet."""

    vertices: np.ndarray
    normals: np.ndarray
    offsets: np.ndarray
    loops: tuple
    tol: float

    # -- construction ---------------------------------------------------------
    @classmethod
    def box(cls, lo, hi, tol: float) -> "ConvexPolytope":
        """The box [lo, hi] (corners ordered like ``geometry.UNIT_CUBE_CORNERS``)."""
        lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
        if np.all(hi - lo > 8.0 * tol):
            return cls(box_corners(lo, hi), BOX_NORMALS.copy(), box_offsets(lo, hi), BOX_LOOPS, tol)
        return cls.from_halfspaces(BOX_NORMALS, box_offsets(lo, hi), tol)

    @classmethod
    def hexahedron(cls, corners, tol: float) -> "ConvexPolytope":
        """A hexahedron (a view frustum) from 8 corners in ``UNIT_CUBE_CORNERS`` order, either orientation."""
        c = np.asarray(corners, dtype=np.float64)
        diagonals = c[_HEX_QUADS[:, 2:]] - c[_HEX_QUADS[:, :2]]      # (6, 2, 3): each quad's two diagonals
        n = cross(diagonals[:, 0], diagonals[:, 1])
        length = np.sqrt(np.einsum("ij,ij->i", n, n))
        if not length.all():
            raise ValueError("degenerate hexahedron: a face has no area")
        n /= length[:, None]
        o = np.einsum("ij,ij->i", n, c[_HEX_QUADS[:, 0]])
        if n[0] @ c[7] > o[0]:                  # the near face's normal points at the far corner: inward
            return cls(c, -n, -o, _HEX_REVERSED, tol)
        return cls(c, n, o, HEXAHEDRON_LOOPS, tol)

    @classmethod
    def from_halfspaces(cls, normals, offsets, tol: float) -> "ConvexPolytope | None":
        """The bounded intersection of ``normals @ x <= offsets`` (vertex enumeration), or None when empty or flat."""
        n, o = unit_halfspaces(normals, offsets)
        n, o = _dedupe_planes(n, o, tol)
        return _enumerate(np.zeros((0, 3)), n, o, _combinations3(len(n)), tol)

    # -- what follows from it -------------------------------------------------
    @cached_property
    def edges(self) -> np.ndarray:
        """(e, 2) sorted vertex index pairs of the loops' edges, lower index first; read-only."""
        pairs = sorted({(a, c) if a < c else (c, a) for loop in self.loops for a, c in zip(loop[-1:] + loop[:-1], loop)})
        edges = np.fromiter(chain.from_iterable(pairs), np.int64, 2 * len(pairs)).reshape(-1, 2)
        edges.flags.writeable = False
        return edges

    @cached_property
    def incidence(self) -> np.ndarray:
        """(n, m): which vertex lies on which facet (by the loops)."""
        inc = np.zeros((len(self.vertices), len(self.loops)), dtype=bool)
        for f, loop in enumerate(self.loops):
            inc[list(loop), f] = True
        return inc

    @cached_property
    def segments(self) -> "Edges":
        """The edges as segments from their lower vertex (t in [0, 1])."""
        a, b = self.vertices[self.edges.T]
        return Edges(a, b - a, np.ones(len(a)))

    def faces(self) -> list[np.ndarray]:
        """The facets as (K, 3) vertex loops, counter-clockwise seen from outside."""
        return [self.vertices[list(loop)] for loop in self.loops]

    @cached_property
    def centroid(self) -> np.ndarray:
        """The mean of the vertices (strictly inside a polytope with volume)."""
        return self.vertices.sum(axis=0) / len(self.vertices)

    @cached_property
    def volume_centroid(self) -> np.ndarray:
        """The centre of the volume (continuous in the polytope, unlike the vertices' mean)."""
        m = self.centroid
        fans = np.array([(loop[0], b, c) for loop in self.loops for b, c in zip(loop[1:-1], loop[2:])]).reshape(-1, 3)
        a, b, c = (self.vertices - m)[fans.T]
        volume = np.abs(np.einsum("ij,ij->i", a, cross(b, c)))
        total = float(volume.sum())
        return m + (volume @ (a + b + c)) / (4.0 * total) if total > 0 else m

    def contains(self, points, tol: float | None = None) -> np.ndarray:
        """Which (N, 3) points lie inside (within ``tol``, default 10 tolerances)."""
        t = 10.0 * self.tol if tol is None else tol
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        return (self.normals @ p.T - self.offsets[:, None]).max(axis=0, initial=-np.inf) <= t

    def translated(self, offset) -> "ConvexPolytope":
        """The same polytope moved by ``offset`` (sharing its edges)."""
        t = np.asarray(offset, dtype=np.float64)
        moved = ConvexPolytope(self.vertices + t, self.normals, self.offsets + self.normals @ t, self.loops, self.tol)
        moved.__dict__["edges"] = self.edges
        return moved

    # -- clip -----------------------------------------------------------------
    def clip(self, normals, offsets) -> "ConvexPolytope | None":
        """This polytope ∩ {normals @ x <= offsets} (unit normals), or None when nothing with volume is left."""
        n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        o = np.asarray(offsets, dtype=np.float64).reshape(-1)
        reach = ((self.vertices @ n.T).max(axis=0) - o).tolist()          # the farthest vertex beyond each plane
        cutting = [j for j, r in enumerate(reach) if r > self.tol]
        if not cutting:
            return self
        n, o = n[cutting], o[cutting]
        vertices, facets = self.vertices.tolist(), list(enumerate(self.loops))
        try:
            for plane, (normal, offset) in enumerate(zip(n.tolist(), o.tolist()), start=len(self.normals)):
                cut = _cut(vertices, facets, normal, offset, self.tol, plane)
                if cut is None:
                    return None
                vertices, facets = cut
        except OpenCut:
            return self._clip_by_enumeration(n, o)
        planes, loops = zip(*facets)
        planes = list(planes)
        return ConvexPolytope(np.array(vertices), np.concatenate([self.normals, n])[planes],
                              np.concatenate([self.offsets, o])[planes], loops, self.tol)

    def _clip_by_enumeration(self, n2: np.ndarray, o2: np.ndarray) -> "ConvexPolytope | None":
        """``clip`` by vertex enumeration, for half-spaces that all cut."""
        n2, o2 = _dedupe_planes(n2, o2, self.tol, self.vertices)
        inside = (self.vertices @ n2.T - o2 <= self.tol).all(axis=1)
        n, o = np.concatenate([self.normals, n2]), np.concatenate([self.offsets, o2])
        return _enumerate(self.vertices[inside], n, o, _combinations3(len(n), len(self.normals)), self.tol,
                          self.incidence[inside])


# ---------------------------------------------------------------------------
# The face walk: B's hot kernel, in plain lists (numpy's cost per call
# outweighs the arithmetic on a 20-vertex body).
# ---------------------------------------------------------------------------

def _cut(vertices: list, facets: list, normal: list, offset: float, tol: float, plane: int):
    """The polytope (``vertices``, ``facets`` as (plane number, loop) pairs) ∩ {normal · x <= offset} by a face
    walk: (vertices, facets) with the new facet (``plane``, its loop) last, unchanged when nothing is cut, None when
    nothing with volume is left. A facet crossed more than twice (rounding) raises OpenCut."""
    nx, ny, nz = normal
    d = [nx * x + ny * y + nz * z - offset for x, y, z in vertices]
    if max(d) <= tol:
        return vertices, facets
    if min(d) >= -tol:
        return None
    beyond = {i for i, e in enumerate(d) if e > tol}
    on = {i for i, e in enumerate(d) if -tol <= e <= tol} if min(map(abs, d)) <= tol else set()
    not_inside = beyond | on
    verts = list(vertices)
    free = sorted(beyond, reverse=True)    # ids of the vertices cut away, for the crossings (lowest first)
    crossing: dict = {}                    # (inside, beyond) vertex pair -> the crossing's id
    cap_next: dict = {}                    # the new facet's edges: vertex -> next vertex
    kept = []
    for facet in facets:
        loop = facet[1]
        if beyond.isdisjoint(loop):                            # kept whole
            if on and len(on.intersection(loop)) > 1:
                for a, c in zip(loop[-1:] + loop[:-1], loop):
                    if a in on and c in on:                    # an edge on the plane: the new facet's, reversed
                        _add_edge(cap_next, c, a)
            kept.append(facet)
            continue
        if not_inside.issuperset(loop):                        # cut away
            continue
        new, turns = [], 0                                     # walked
        p, p_out = loop[-1], loop[-1] in beyond
        for q in loop:
            q_out = q in beyond
            if p_out != q_out:                                 # the edge p -> q passes the plane
                turns += 1
                inner, outer = (q, p) if p_out else (p, q)
                if inner in on:
                    x = inner
                else:
                    x = crossing.get((inner, outer))
                    if x is None:                              # the crossing, made once per edge
                        t = d[inner] / (d[inner] - d[outer])
                        (ax, ay, az), (bx, by, bz) = vertices[inner], vertices[outer]
                        point = (ax + t * (bx - ax), ay + t * (by - ay), az + t * (bz - az))
                        x = crossing[(inner, outer)] = free.pop() if free else len(verts)
                        if x < len(verts):
                            verts[x] = point
                        else:
                            verts.append(point)
                    new.append(x)
                if p_out:
                    back = x
                else:
                    leave = x
            if not q_out:
                new.append(q)
            p, p_out = q, q_out
        if turns != 2:
            raise OpenCut("a facet crosses the plane more than twice")
        _add_edge(cap_next, back, leave)
        kept.append((facet[0], new))
    kept.append((plane, closed_loop(cap_next)))
    return _close_gaps(verts, kept, free) if free else (verts, kept)


def _close_gaps(verts: list, facets: list, gone) -> tuple[list, list]:
    """Vertices and facets renumbered without the ids ``gone``."""
    gone = set(gone)
    live = [v for v in range(len(verts)) if v not in gone]
    index = dict(zip(live, range(len(live))))
    return [verts[v] for v in live], [(f, [index[v] for v in loop]) for f, loop in facets]


def _add_edge(next_vertex: dict, a: int, b: int) -> None:
    """The edge a -> b of a loop being chained; OpenCut when a already has one."""
    if a in next_vertex:
        raise OpenCut("two edges of the new facet leave one vertex")
    next_vertex[a] = b


def closed_loop(next_vertex: dict) -> list:
    """The loop of the edges ``next_vertex`` (vertex -> next vertex) from its least vertex; OpenCut unless they close
    into one loop of at least three (a cut's new facet, a sun's cap over the silhouette)."""
    if len(next_vertex) < 3:
        raise OpenCut("the cut leaves no new facet")
    start = min(next_vertex)
    loop, v = [start], next_vertex[start]
    while v != start:
        if v not in next_vertex or len(loop) > len(next_vertex):
            raise OpenCut("the new facet's edges do not close into one loop")
        loop.append(v)
        v = next_vertex[v]
    if len(loop) != len(next_vertex):
        raise OpenCut("the new facet's edges form more than one loop")
    return loop


# ---------------------------------------------------------------------------
# Sections: Cyrus-Beck clips of edges.
# ---------------------------------------------------------------------------

class Edges(NamedTuple):
    """Segments start + t·step for 0 <= t <= end (end = inf: a ray), in arrays (..., s, 3), (..., s, 3), (..., s)."""

    start: np.ndarray
    step: np.ndarray
    end: np.ndarray


def clip_segments(edges: Edges, normals: np.ndarray, offsets: np.ndarray,
                  own: tuple[int, int] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Cyrus-Beck: the stretch [t_lo, t_hi] of each segment (..., s) inside every half-space ``normals · x <= offsets``
    (..., m); empty where t_lo > t_hi. ``own`` = (m', s'): the first m' half-spaces leave the first s'
    segments whole."""
    rate = normals @ np.swapaxes(edges.step, -1, -2) + 0.0                   # (..., m, s)
    room = offsets[..., None] - normals @ np.swapaxes(edges.start, -1, -2)
    if own is not None:
        room[..., :own[0], :own[1]] = room[..., own[0]:, own[1]:] = np.inf
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        ratio = room / rate
    rising = rate >= 0
    t_hi = np.minimum(np.fmin.reduce(np.where(rising, ratio, np.inf), axis=-2), edges.end)
    t_lo = np.maximum(np.fmax.reduce(np.where(rising, -np.inf, ratio), axis=-2), 0.0)
    return t_lo, t_hi


def section_points(poly: ConvexPolytope, normals: np.ndarray, offsets: np.ndarray, edges: Edges,
                   tol: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Points whose hull is ``poly`` ∩ Q_k for k bodies Q_k (facets ``normals`` (k, m, 3), ``offsets`` (k, m),
    ``edges`` (k, s)), within ``tol``: the points (N, 3) and the body of each (N,), body by body."""
    tol = poly.tol if tol is None else tol
    mine, k = poly.segments, len(normals)

    def per_body(a: np.ndarray, b: np.ndarray) -> np.ndarray:        # poly's (shared by every body), then the body's
        return np.concatenate([a[None].repeat(k, axis=0), b], axis=1)

    # Per body: poly's facets and edges, then the body's.
    both = Edges(per_body(mine.start, edges.start), per_body(mine.step, edges.step), per_body(mine.end, edges.end))
    t_lo, t_hi = clip_segments(both, per_body(poly.normals, normals), per_body(poly.offsets, offsets) + tol,
                               own=(len(poly.normals), len(mine.end)))
    hit = t_lo <= t_hi                                                          # (k, segments)
    ends = np.stack([t_lo[hit], t_hi[hit]], axis=1)                            # (hits, 2), body by body
    points = both.start[hit][:, None] + ends[..., None] * both.step[hit][:, None]     # (hits, 2, 3)
    return points.reshape(-1, 3), np.repeat(np.nonzero(hit)[0], 2)


# ---------------------------------------------------------------------------
# Vertex enumeration: the fallback for cuts the face walk cannot order.
# ---------------------------------------------------------------------------

def _combinations3(m: int, first_new: int = 0) -> np.ndarray:
    """(C(m, 3), 3) triples i < j < k, k >= ``first_new``, lexicographic."""
    return np.array([t for t in combinations(range(m), 3) if t[2] >= first_new], dtype=np.int64).reshape(-1, 3)


def unit_halfspaces(normals, offsets) -> tuple[np.ndarray, np.ndarray]:
    """The half-spaces ``normals @ x <= offsets`` with unit normals (zero normals dropped)."""
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    o = np.asarray(offsets, dtype=np.float64).reshape(-1)
    length = np.sqrt(np.einsum("ij,ij->i", n, n))
    good = length > 0
    return n[good] / length[good, None], o[good] / length[good]


def coincident_planes(n: np.ndarray, o: np.ndarray, points: np.ndarray | None, tol: float) -> np.ndarray:
    """(m, m): which planes are one where it matters: nearly the same normal and signed distances within ``tol``
    of each other at every one of ``points`` (without points: equal offsets)."""
    near = n @ n.T > 1.0 - 1e-12
    if points is None or len(points) == 0:
        return near & (np.abs(o[:, None] - o[None, :]) <= tol)
    dist = points @ n.T - o                                   # (v, m)
    spread = np.abs(dist[:, :, None] - dist[:, None, :]).max(axis=0)
    return near & (spread <= tol)


def _dedupe_planes(n: np.ndarray, o: np.ndarray, tol: float,
                   points: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Drop planes equal (within ``tol`` over ``points``) to an earlier one."""
    keep = ~np.any(np.tril(coincident_planes(n, o, points, tol), -1), axis=1)
    return n[keep], o[keep]


def _enumerate(kept: np.ndarray, n: np.ndarray, o: np.ndarray, tri: np.ndarray, tol: float,
               kept_inc: np.ndarray | None = None) -> ConvexPolytope | None:
    """The polytope of the planes ``n · x <= o`` whose vertices are the ``kept`` points (incidence ``kept_inc``) and
    the feasible solutions of the triples ``tri`` (Cramer's rule)."""
    m = len(n)
    scale_o = float(np.abs(o).max()) + tol
    cand, radius = kept, np.zeros(len(kept))
    inc = np.zeros((len(kept), m), dtype=bool)
    if kept_inc is not None and len(kept):
        inc[:, : kept_inc.shape[1]] = kept_inc
    if len(tri):
        i, j, k = tri.T
        cjk = np.cross(n[j], n[k])
        det = np.einsum("ij,ij->i", n[i], cjk)
        good = np.abs(det) > DET_MIN
        i, j, k, cjk, det = i[good], j[good], k[good], cjk[good], det[good]
        # Cramer's rule: x = (o_i (n_j x n_k) + o_j (n_k x n_i) + o_k (n_i x n_j)) / det.
        x = (o[i, None] * cjk + o[j, None] * np.cross(n[k], n[i]) + o[k, None] * np.cross(n[i], n[j])) / det[:, None]
        # Rounding error of the solve grows as the planes get closer to sharing a line; it
        # widens the feasibility test and (capped, so an ill-conditioned point cannot swallow
        # distinct vertices) the merge and incidence reach.
        err = 16.0 * EPS * scale_o / np.abs(det)
        feasible = (x @ n.T - o).max(axis=1) <= tol + err
        i, j, k, x, err = i[feasible], j[feasible], k[feasible], x[feasible], np.minimum(err, SNAP * tol)[feasible]
        solved = np.zeros((len(x), m), dtype=bool)
        rows = np.arange(len(x))
        solved[rows, i] = solved[rows, j] = solved[rows, k] = True
        cand, radius, inc = np.concatenate([kept, x]), np.concatenate([radius, err]), np.concatenate([inc, solved])
    if len(cand) < 4:
        return None
    inc |= np.abs(cand @ n.T - o) <= (64.0 * EPS * scale_o + radius)[:, None]
    # A vertex on more than three planes is solved several times, and vertices closer than
    # SNAP tol merge (plus their rounding-error bound), with the planes of all of them.
    keep, group = _merge_groups(cand, SNAP * tol, radius)
    member = np.zeros((len(keep), len(cand)), dtype=np.uint8)
    member[group, np.arange(len(cand))] = 1
    return _tidy(cand[keep] + 0.0, n, o, tol, (member @ inc.astype(np.uint8)) > 0)


def _tidy(verts: np.ndarray, n: np.ndarray, o: np.ndarray, tol: float, inc: np.ndarray) -> ConvexPolytope | None:
    """The polytope of these vertices, planes and incidence, nearly coincident planes merged, slivers and vertices
    on fewer than three facets dropped."""
    m = len(n)
    near = coincident_planes(n, o, verts, COINCIDENT * tol)
    np.fill_diagonal(near, False)
    rank = m - np.arange(m)                         # ties: the earlier (older) plane wins
    facet = np.ones(m, dtype=bool)
    for _ in range(4):
        if len(verts) < 4:
            return None
        facet &= inc.sum(axis=0) >= 3
        shared = inc.T.astype(np.float64) @ inc
        for a, b in zip(*np.nonzero(np.triu(near & (shared >= 1) & np.outer(facet, facet), 1))):
            if facet[a] and facet[b]:
                inc[:, a] |= inc[:, b]
                facet[b] = False
        count = inc.sum(axis=0)
        shared = inc.T.astype(np.float64) @ inc
        key = count * (m + 1) + rank
        facet &= ~((shared == count[None, :]) & (key[:, None] > key[None, :]) & facet[:, None]).any(axis=0)
        inc &= facet
        corner = inc.sum(axis=1) >= 3
        if corner.all():
            break
        verts, inc = verts[corner], inc[corner]
    if facet.sum() < 4 or len(verts) < 4:
        return None
    n, o, inc = n[facet], o[facet], inc[:, facet]
    if np.any(inc.all(axis=0)):                     # no volume: every vertex on one facet plane
        return None
    return ConvexPolytope(verts, n, o, _loops_from_incidence(verts, n, inc), tol)


def _loops_from_incidence(verts: np.ndarray, normals: np.ndarray, inc: np.ndarray) -> tuple:
    """Each facet's vertices ordered counter-clockwise about its centre."""
    f, v = np.nonzero(inc.T)
    counts = np.bincount(f, minlength=len(normals))
    pts = verts[v]
    centre = np.stack([np.bincount(f, weights=pts[:, c], minlength=len(counts)) for c in range(3)], axis=1)
    centre /= np.maximum(counts, 1)[:, None]
    axis = np.eye(3)[np.argmin(np.abs(normals), axis=1)]
    u = np.cross(normals, axis)
    u /= np.sqrt((u * u).sum(axis=1))[:, None]
    w = np.cross(normals, u)
    rel = pts - centre[f]
    angle = np.arctan2(np.einsum("ij,ij->i", rel, w[f]), np.einsum("ij,ij->i", rel, u[f]))
    ids = v[np.lexsort((angle, f))].tolist()
    ends = np.cumsum(counts).tolist()
    return tuple(tuple(ids[e - c: e]) for e, c in zip(ends, counts.tolist()))


MERGE_PAIRS = 1 << 22
"""Point pairs ``_merge_groups`` compares at once, ~40 bytes each (20,000 outline corners in one go: 16 GB)."""


def _merge_groups(p: np.ndarray, tol, radius: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Merge points closer than ``tol`` (plus the larger ``radius``), transitively, each joining the first point
    in lexicographic order within reach: (indices kept, each point's group's position among them). Rows go in
    blocks, each against the points within reach in x: a slice, as x sorts first; ``p`` is not empty."""
    order = np.lexsort((p[:, 2], p[:, 1], p[:, 0]))
    q = p[order]
    reach = np.full(len(q), float(tol)) if radius is None else tol + radius[order]
    span, rows, rep = 2.0 * float(reach.max()), max(1, MERGE_PAIRS // len(q)), np.empty(len(q), dtype=np.int64)
    for a in range(0, len(q), rows):
        b = min(a + rows, len(q))
        lo, hi = np.searchsorted(q[:, 0], q[a, 0] - span, "left"), np.searchsorted(q[:, 0], q[b - 1, 0] + span, "right")
        diff = q[a:b, None, :] - q[None, lo:hi, :]
        close = np.einsum("ijk,ijk->ij", diff, diff) <= np.square(np.maximum.outer(reach[a:b], reach[lo:hi]))
        rep[a:b] = lo + np.argmax(close, axis=1)   # first point within reach (itself at the latest)
    while True:                                    # follow chains to their first point
        nxt = rep[rep]
        if np.array_equal(nxt, rep):
            break
        rep = nxt
    roots = np.nonzero(rep == np.arange(len(q)))[0]
    slot = np.zeros(len(q), dtype=np.int64)
    slot[roots] = np.arange(len(roots))
    group = np.empty(len(q), dtype=np.int64)
    group[order] = slot[rep]
    return order[roots], group


# ---------------------------------------------------------------------------
# Planar polygons and face lists.
# ---------------------------------------------------------------------------

def unique_points(points, tol: float) -> np.ndarray:
    """Points merged within ``tol`` in a deterministic lexicographic order (the earlier one kept)."""
    p = np.unique(np.asarray(points, dtype=np.float64).reshape(-1, 3), axis=0)  # exact copies first, by sorting
    return p[_merge_groups(p, tol)[0]] if len(p) else p


def convex_polygon_on_plane(points, normal, tol: float) -> np.ndarray | None:
    """The convex hull, CCW about ``normal``, of points on one plane (Andrew's monotone
    chain, dropping points within ``tol`` of each other or of a hull edge), or None without area."""
    pts = unique_points(points, tol)
    if len(pts) < 3:
        return None
    normal = np.asarray(normal, dtype=np.float64)
    rel = pts - pts.mean(axis=0)
    far = np.einsum("ij,ij->i", rel, rel)
    length = float(far.max()) ** 0.5
    if length <= tol:
        return None
    u = rel[int(np.argmax(far))] / length                  # in-plane axes: u towards the farthest point,
    xy = rel @ np.array([u, cross(normal, u)]).T        # v = normal x u
    order = np.lexsort((xy[:, 1], xy[:, 0]))
    q = xy[order].tolist()
    area_tol = tol * max(float(np.ptp(xy, axis=0).max()), tol)

    def half(indices) -> list:
        kept: list = []
        for k in indices:
            while len(kept) >= 2 and _turn(q[kept[-2]], q[kept[-1]], q[k]) <= area_tol:
                kept.pop()
            kept.append(k)
        return kept

    hull = half(range(len(q)))[:-1] + half(range(len(q) - 1, -1, -1))[:-1]
    return pts[order[hull]] if len(hull) >= 3 else None


def plane_section(poly: ConvexPolytope, normal, offset: float) -> np.ndarray | None:
    """P ∩ {normal · x = offset} as a convex polygon CCW about ``normal``, or None without area: the face walk's new
    facet when every turn exceeds 2·tol·D, else the hull of the crossings and P's vertices on the plane."""
    n = np.asarray(normal, dtype=np.float64)
    height = poly.vertices @ n - offset
    on = np.abs(height) <= poly.tol
    crossings = None
    if not on.any():
        try:
            cut = _cut(poly.vertices.tolist(), list(enumerate(poly.loops)), n.tolist(), offset, poly.tol, -1)
        except OpenCut:
            cut = None
        if cut is not None and cut[1][-1][0] == -1:                  # (P crossed: its new facet comes last)
            vertices, (*facets, (_, cap)) = cut
            section = [vertices[v] for v in _from_first_crossing(facets, cap)]
            if _turns_exceed(section, n, poly.tol):
                return np.array(section)
            crossings = np.array(section)
    if crossings is None:
        crossings = _crossings(poly, height)
    return convex_polygon_on_plane(np.concatenate([poly.vertices[on] - np.outer(height[on], n), crossings]), n, poly.tol)


def _from_first_crossing(facets: list, cap: list) -> list:
    """The new facet's loop from where the first facet it crosses comes back below the plane."""
    on_cap = set(cap)
    back = next(b for _, loop in facets for a, b in zip(loop[-1:] + loop[:-1], loop) if a in on_cap and b in on_cap)
    at = cap.index(back)
    return cap[at:] + cap[:at]


def _turns_exceed(polygon: list, normal: np.ndarray, tol: float) -> bool:
    """Whether the polygon turns left about ``normal`` at every vertex by more than 2·tol·D (D >= its diameter)."""
    p = np.array(polygon)
    limit = 2.0 * tol * max(2.0 * float(np.abs(p - p[0]).sum(axis=1).max()), tol)
    edges = np.concatenate([p[1:], p[:1]]) - p
    return bool(np.all(cross(np.concatenate([edges[-1:], edges[:-1]]), edges) @ normal > limit))


def _crossings(poly: ConvexPolytope, height: np.ndarray) -> np.ndarray:
    """Where P's edges cross the plane, both ends beyond the tolerance (``height``: the vertices')."""
    a, b = poly.edges.T
    crossed = ((height[a] > poly.tol) & (height[b] < -poly.tol)) | ((height[a] < -poly.tol) & (height[b] > poly.tol))
    a, b = a[crossed], b[crossed]
    t = height[a] / (height[a] - height[b])
    return poly.vertices[a] + t[:, None] * (poly.vertices[b] - poly.vertices[a])


def _turn(o, a, b) -> float:
    """(a - o) x (b - o) for 2D points: positive for a left turn."""
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def hexahedron_faces(corners) -> list[np.ndarray]:
    """The six quads of 8 corners in ``UNIT_CUBE_CORNERS`` order (e.g. a view frustum)."""
    return list(np.asarray(corners, dtype=np.float64)[_HEX_QUADS])


_HEX_QUADS = np.array(HEXAHEDRON_LOOPS)
_HEX_REVERSED = tuple(loop[::-1] for loop in HEXAHEDRON_LOOPS)
