"""Convex polyhedra in float64, deterministic, with tolerances passed in
(relative to the scene's scale).

* :class:`ConvexPolytope` - what the warp core uses: vertices, facet planes and
  their incidence, built by vectorised vertex enumeration from half-spaces
  (``from_halfspaces``, ``clip``, ``box``, ``from_corners``); ``faces()`` gives
  the facets as ordered loops, ``edges()`` the edges as vertex pairs.
* Face lists - a polyhedron as a list of planar convex faces, each an ordered
  (K, 3) array (outward counter-clockwise); ``clip_faces`` clips one by a
  half-space (Sutherland-Hodgman per face plus a cap, so the body is never left
  open). Kept for callers that work on face lists (e.g. plane maps); about a
  hundred times slower than ``ConvexPolytope.clip``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from itertools import chain

import numpy as np

from . import brep as _brep
from .brep import Brep, OpenCut

EPS = float(np.finfo(np.float64).eps)


@dataclass(frozen=True)
class Plane:
    """The half-space ``normal . x <= offset`` (normal of unit length)."""

    normal: np.ndarray
    offset: float

    def distance(self, points) -> np.ndarray:
        return np.asarray(points, dtype=np.float64) @ self.normal - self.offset

    @classmethod
    def through(cls, point, normal) -> "Plane":
        n = np.asarray(normal, dtype=np.float64)
        n = n / np.linalg.norm(n)
        return cls(n, float(n @ np.asarray(point, dtype=np.float64)))


def box_faces(lo, hi) -> list[np.ndarray]:
    """The six faces of the box [lo, hi], outward counter-clockwise."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    c = np.array([[hi[0] if i & 1 else lo[0], hi[1] if i & 2 else lo[1], hi[2] if i & 4 else lo[2]] for i in range(8)])
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    return [c[list(q)] for q in quads]


def hexahedron_faces(corners) -> list[np.ndarray]:
    """Faces of a hexahedron given as 8 corners ordered like geometry.UNIT_CUBE_CORNERS
    (near face first, x fastest then y) - e.g. a view frustum."""
    c = np.asarray(corners, dtype=np.float64)
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    return [c[list(q)] for q in quads]


def float_rows(rows, width: int = 3) -> np.ndarray:
    """(n, width) float64 array of n rows of plain floats (e.g. a :class:`~.brep.Brep`'s
    vertices): np.fromiter over them flat, as np.array on a list of tuples costs ~1.6x more."""
    return np.fromiter(chain.from_iterable(rows), np.float64, width * len(rows)).reshape(-1, width)


def _polygon_on_plane(points: np.ndarray, normal: np.ndarray, tol: float) -> np.ndarray | None:
    """Convex hull (ordered CCW about ``normal``) of points lying on one plane."""
    pts = unique_points(points, tol)
    if len(pts) < 3:
        return None
    rel = pts - pts.mean(axis=0)
    far = np.einsum("ij,ij->i", rel, rel)
    i = int(np.argmax(far))
    length = float(far[i]) ** 0.5
    if length <= tol:
        return None
    # In-plane axes: u towards the farthest point, v = normal x u.
    ux, uy, uz = (rel[i] / length).tolist()
    nx, ny, nz = (float(c) for c in normal)
    axes = np.array([[ux, uy, uz], [ny * uz - nz * uy, nz * ux - nx * uz, nx * uy - ny * ux]])
    xy = rel @ axes.T
    order = np.lexsort((xy[:, 1], xy[:, 0]))
    xy = xy[order]
    q = xy.tolist()
    # Andrew's monotone chain (plain floats), dropping collinear points within tolerance.
    area_tol = tol * max(float((xy.max(axis=0) - xy.min(axis=0)).max()), tol)

    def chain(indices) -> list:
        kept: list = []
        for k in indices:
            bx, by = q[k]
            while len(kept) >= 2:
                ox, oy = q[kept[-2]]
                ax, ay = q[kept[-1]]
                if (ax - ox) * (by - oy) - (ay - oy) * (bx - ox) > area_tol:
                    break
                kept.pop()
            kept.append(k)
        return kept

    hull = chain(range(len(q)))[:-1] + chain(range(len(q) - 1, -1, -1))[:-1]
    if len(hull) < 3:
        return None
    return pts[order[hull]]


def unique_points(points, tol: float) -> np.ndarray:
    """Points merged within ``tol`` in a deterministic lexicographic order (a
    point is dropped when an earlier one in that order lies within ``tol``)."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(p) == 0:
        return p
    return p[_merge_points(p, tol)]


def clip_faces(faces: list[np.ndarray], plane: Plane, tol: float) -> list[np.ndarray]:
    """Clip a closed convex polyhedron by a half-space, capping the cut."""
    out: list[np.ndarray] = []
    cut: list[np.ndarray] = []
    n, o = plane.normal, plane.offset
    for poly in faces:
        d = poly @ n - o
        d = np.where(np.abs(d) <= tol, 0.0, d)
        if np.all(d <= 0):
            out.append(poly)
            cut.extend(poly[d == 0])
            continue
        if np.all(d >= 0):
            cut.extend(poly[d == 0])
            continue
        kept: list[np.ndarray] = []
        k = len(poly)
        for i in range(k):
            a, b = poly[i], poly[(i + 1) % k]
            da, db = d[i], d[(i + 1) % k]
            if da <= 0:
                kept.append(a)
                if da == 0:
                    cut.append(a)
            if (da < 0 < db) or (db < 0 < da):
                t = da / (da - db)
                x = a + t * (b - a)
                kept.append(x)
                cut.append(x)
        face = _polygon_on_plane(np.asarray(kept), _face_normal(poly), tol)
        if face is not None:
            out.append(face)
    if out and cut:
        cap = _polygon_on_plane(np.asarray(cut), n, tol)
        if cap is not None:
            out.append(cap)
    return out if len(out) >= 4 else []


def _face_normal(poly: np.ndarray) -> np.ndarray:
    """Newell's normal of a planar polygon (outward for CCW order)."""
    n = np.zeros(3)
    for i in range(len(poly)):
        a, b = poly[i], poly[(i + 1) % len(poly)]
        n += np.array([(a[1] - b[1]) * (a[2] + b[2]), (a[2] - b[2]) * (a[0] + b[0]), (a[0] - b[0]) * (a[1] + b[1])])
    norm = np.linalg.norm(n)
    return n / norm if norm > 0 else n


def face_planes(faces: list[np.ndarray]) -> list[Plane]:
    """Outward half-spaces of the faces of a closed convex polyhedron."""
    centre = np.mean(np.concatenate(faces), axis=0)
    planes = []
    for f in faces:
        n = _face_normal(f)
        if not np.any(n):
            continue
        p = Plane(n, float(n @ f.mean(axis=0)))
        if p.distance(centre[None])[0] > 0:
            p = Plane(-n, -p.offset)
        planes.append(p)
    return planes


def face_edges(faces: list[np.ndarray], tol: float) -> list[tuple[np.ndarray, np.ndarray, int, int]]:
    """Edges (a, b, face i, face j) shared by two faces of a closed polyhedron."""
    verts = unique_points(np.concatenate(faces), tol)
    def idx(p):
        return int(np.argmin(np.linalg.norm(verts - p, axis=1)))
    owner: dict[tuple[int, int], list[int]] = {}
    for fi, f in enumerate(faces):
        ids = [idx(p) for p in f]
        for k in range(len(ids)):
            a, b = ids[k], ids[(k + 1) % len(ids)]
            if a != b:
                owner.setdefault((min(a, b), max(a, b)), []).append(fi)
    return [(verts[a], verts[b], fs[0], fs[1]) for (a, b), fs in sorted(owner.items()) if len(fs) >= 2]


# ---------------------------------------------------------------------------
# ConvexPolytope: vertices + facet half-spaces + incidence, fully vectorised.
# ---------------------------------------------------------------------------

SNAP = 4.0
"""Vertices closer than SNAP tolerances are one vertex, and a vertex within SNAP
tolerances of a plane lies on it: one scale for both, so near-degenerate
corners (a plane passing a vertex at a few tolerances) give consistent faces."""

COINCIDENT = 1000.0
"""Facet planes whose signed distances differ by less than this many tolerances
at every vertex are one facet. It is the scale below which a solid counts as
flat (B is padded to at least this thickness); measured on 3000 random awkward
cuts of a box, it leaves no falsely empty clip and no vertex outside a cut, where
an angle test alone (1.4e-6 rad) emptied nearly whole boxes."""

DET_MIN = 1e-13
"""Triples of planes whose normals' triple product is below this are treated as
meeting in no single point (parallel or sharing a line)."""

_COMBOS: dict[tuple[int, int], np.ndarray] = {}
_PAIRS: dict[int, tuple[np.ndarray, np.ndarray]] = {}


def _pairs(m: int) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs i < j below ``m`` (cached)."""
    p = _PAIRS.get(m)
    if p is None:
        p = _PAIRS[m] = np.triu_indices(m, 1)
    return p


def _combinations3(m: int, first_new: int = 0) -> np.ndarray:
    """(C(m, 3), 3) index triples i < j < k in lexicographic order with
    k >= ``first_new`` (triples holding at least one new plane; cached)."""
    c = _COMBOS.get((m, first_new))
    if c is None:
        i, j, k = np.meshgrid(np.arange(m), np.arange(m), np.arange(m), indexing="ij")
        sel = (i < j) & (j < k) & (k >= first_new)
        c = np.stack([i[sel], j[sel], k[sel]], axis=1)
        _COMBOS[(m, first_new)] = c
    return c


def cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross products of (N, 3) arrays (np.cross without its overhead)."""
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
                     a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)


def _perpendiculars(n: np.ndarray) -> np.ndarray:
    """Unit vectors perpendicular to each row of ``n`` (rows of unit length),
    each away from the axis the row is least aligned with (as geometry.perpendicular)."""
    axis = np.argmin(np.abs(n), axis=1)
    e = np.zeros_like(n)
    e[np.arange(len(n)), axis] = 1.0
    u = cross_rows(n, e)
    return u / np.sqrt((u * u).sum(axis=1))[:, None]


def _unit_rows(normals, offsets) -> tuple[np.ndarray, np.ndarray]:
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    o = np.asarray(offsets, dtype=np.float64).reshape(-1)
    length = np.sqrt(np.einsum("ij,ij->i", n, n))
    if length.all():
        return n / length[:, None], o / length
    good = length > 0
    return n[good] / length[good, None], o[good] / length[good]


def coincident_planes(n: np.ndarray, o: np.ndarray, points: np.ndarray | None, tol: float) -> np.ndarray:
    """(m, m) which planes are one plane where it matters: nearly the same
    normal, and signed distances within ``tol`` of each other at every one of
    ``points`` (the polytope's vertices; without points, equal offsets). An
    angle alone is no test: planes 1e-6 rad apart through one line are 1e-6 of
    the extent apart at its far end, a real (shallow) edge, not a duplicate."""
    near = n @ n.T > 1.0 - 1e-12
    if points is None or len(points) == 0:
        return near & (np.abs(o[:, None] - o[None, :]) <= tol)
    dist = points @ n.T - o                                   # (v, m)
    spread = np.abs(dist[:, :, None] - dist[:, None, :]).max(axis=0)
    return near & (spread <= tol)


def _dedupe_planes(n: np.ndarray, o: np.ndarray, tol: float,
                   points: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Drop planes equal (within ``tol`` over ``points``) to an earlier one."""
    if len(n) < 2:
        return n, o
    keep = ~np.any(np.tril(coincident_planes(n, o, points, tol), -1), axis=1)
    return n[keep], o[keep]


def _merge_groups(p: np.ndarray, tol, radius: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Merge points closer than ``tol`` (plus the larger of their ``radius``
    entries, e.g. rounding-error bounds). Returns (indices of the points kept,
    in lexicographic order - deterministic; for every point, the position of
    its group's kept point in that list). Each point joins the first point (in
    lexicographic order) within reach, transitively."""
    if len(p) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    order = np.lexsort((p[:, 2], p[:, 1], p[:, 0]))
    q = p[order]
    diff = q[:, None, :] - q[None, :, :]
    if radius is None:
        close = np.einsum("ijk,ijk->ij", diff, diff) <= float(tol) ** 2
    else:
        r = tol + radius[order]
        close = np.einsum("ijk,ijk->ij", diff, diff) <= np.square(np.maximum.outer(r, r))
    rep = np.argmax(close, axis=1)                 # first point within reach (itself at the latest)
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


def _merge_points(p: np.ndarray, tol, radius: np.ndarray | None = None) -> np.ndarray:
    """Indices of the points kept by ``_merge_groups`` (lexicographic order)."""
    return _merge_groups(p, tol, radius)[0]


@dataclass(frozen=True)
class ConvexPolytope:
    """A closed convex polytope with both descriptions, in float64.

    ``vertices`` (n, 3); ``normals``/``offsets`` the facet half-spaces
    ``normals @ x <= offsets`` (unit outward normals); ``incidence`` (n, m)
    which vertex lies on which facet; ``loops`` each facet's vertex indices
    counter-clockwise seen from outside (derived from the incidence when not
    given). ``tol`` is the length below which points and planes are considered
    to meet. Every construction is deterministic.

    ``clip`` cuts the boundary plane by plane (:mod:`.brep`, a dozen plain
    Python operations per vertex and no numpy overhead), so its faces close by
    construction. ``from_halfspaces``, and ``clip`` when a cut is too
    degenerate for the face walk (``brep.OpenCut``), use vertex enumeration:
    every triple of planes is solved at once (vectorised), infeasible and
    duplicate solutions dropped, so a clip with k cutting planes on an m-facet
    polytope solves C(m+k, 3) - C(m, 3) triples; its vertices come sorted
    lexicographically and its planes without redundant ones.
    """

    vertices: np.ndarray
    normals: np.ndarray
    offsets: np.ndarray
    incidence: np.ndarray
    tol: float
    loops: tuple | None = field(default=None, compare=False, repr=False)

    # -- construction --------------------------------------------------------
    @classmethod
    def box(cls, lo, hi, tol: float) -> "ConvexPolytope":
        lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
        if np.all(hi - lo > 8.0 * tol):
            # Corners in lexicographic order (bit 2: x, bit 1: y, bit 0: z) and the
            # facets -x, -y, -z, +x, +y, +z with their known incidence.
            verts = np.where(_BOX_BITS, hi, lo) + 0.0
            return cls(verts, _BOX_NORMALS.copy(), np.concatenate([-lo, hi]), _BOX_INCIDENCE.copy(), tol,
                       _BOX_LOOPS)
        return cls.from_corners(np.array([[hi[0] if i & 1 else lo[0], hi[1] if i & 2 else lo[1],
                                           hi[2] if i & 4 else lo[2]] for i in range(8)]), tol)

    @classmethod
    def from_corners(cls, corners, tol: float) -> "ConvexPolytope":
        """A hexahedron (box, frustum) from 8 corners ordered like
        ``geometry.UNIT_CUBE_CORNERS``; planes from each face's Newell normal."""
        c = np.asarray(corners, dtype=np.float64).reshape(8, 3)
        pts = c[_HEX_QUAD_INDEX]                     # (6, 4, 3)
        # A quad's normal is the cross product of its diagonals (exact for planar quads).
        n = cross_rows(pts[:, 2] - pts[:, 0], pts[:, 3] - pts[:, 1])
        n /= np.sqrt((n * n).sum(axis=1))[:, None]
        o = (n * pts.mean(axis=1)).sum(axis=1)
        centre = c.mean(axis=0)
        flip = n @ centre - o > 0
        n[flip], o[flip] = -n[flip], -o[flip]
        edges = c[_HEX_EDGE_INDEX[0]] - c[_HEX_EDGE_INDEX[1]]
        if float((edges * edges).sum(axis=1).min()) > (8.0 * tol) ** 2:
            # 8 distinct corners: each on the 3 faces the corner ordering says (when they are planar).
            order = np.lexsort((c[:, 2], c[:, 1], c[:, 0]))
            verts = c[order] + 0.0
            inc = _HEX_INCIDENCE[order]
            if np.all(np.abs((verts @ n.T - o)[inc]) <= 4.0 * tol):
                # Quads whose normal had to be flipped run the other way round.
                at = np.argsort(order).tolist()
                loops = tuple(tuple(at[i] for i in (q[::-1] if f else q)) for q, f in zip(_HEX_QUADS, flip.tolist()))
                return cls(verts, n, o, inc.copy(), tol, loops)
            poly = cls._finish(verts, n, o, tol)
        else:
            poly = cls._finish(c[_merge_points(c, SNAP * tol)] + 0.0, n, o, tol)
        if poly is None or len(poly.normals) != 6:
            poly = cls.from_halfspaces(n, o, tol)      # e.g. corners not quite planar per face
        if poly is None:
            raise ValueError("degenerate hexahedron")
        return poly

    @classmethod
    def from_brep(cls, b: Brep, tol: float) -> "ConvexPolytope":
        """The polytope of a boundary representation (:mod:`.brep`)."""
        verts = float_rows(b.vertices)
        verts += 0.0                       # no negative zeros
        normals = float_rows(b.normals)
        m = len(b.loops)
        inc = np.zeros((len(verts), m), dtype=bool)
        inc.ravel()[[v * m + f for f, loop in enumerate(b.loops) for v in loop]] = True     # (vertex, facet)
        return cls(verts, normals, np.array(b.offsets, dtype=np.float64), inc, tol, tuple(map(tuple, b.loops)))

    def brep(self) -> Brep:
        """This polytope's boundary as plain lists (:mod:`.brep`)."""
        return Brep(self.vertices.tolist(), self.normals.tolist(), self.offsets.tolist(),
                    [list(loop) for loop in self.facet_loops()])

    @classmethod
    def from_faces(cls, faces: list[np.ndarray], tol: float) -> "ConvexPolytope | None":
        """The polytope bounded by the planes of a closed convex face list."""
        planes = face_planes([np.asarray(f, dtype=np.float64) for f in faces])
        if len(planes) < 4:
            return None
        return cls.from_halfspaces(np.array([p.normal for p in planes]), np.array([p.offset for p in planes]), tol)

    @classmethod
    def from_halfspaces(cls, normals, offsets, tol: float) -> "ConvexPolytope | None":
        """The bounded intersection of half-spaces ``normals @ x <= offsets``, or
        None when it is empty or has no volume (within ``tol``)."""
        n, o = _unit_rows(normals, offsets)
        n, o = _dedupe_planes(n, o, tol)
        if len(n) < 4:
            return None
        return cls._build(np.zeros((0, 3)), n, o, _combinations3(len(n)), tol)

    @classmethod
    def _build(cls, kept: np.ndarray, n: np.ndarray, o: np.ndarray, tri: np.ndarray, tol: float,
               kept_inc: np.ndarray | None = None):
        """Vertices = ``kept`` points (on the planes ``kept_inc`` says, columns
        for the first planes of ``n``) plus the feasible solutions of plane
        ``tri``ples. A vertex lies on the planes it was solved from, on the planes
        it lay on before, and on any plane within rounding error of it: the
        incidence comes from the construction, so planes that pass a vertex at a
        few tolerances (nearly degenerate corners) do not tangle the faces."""
        m = len(n)
        scale_o = float(np.abs(o).max()) + tol
        tight = 64.0 * EPS * scale_o
        cand, radius = kept, np.zeros(len(kept))
        inc = np.zeros((len(kept), m), dtype=bool)
        if kept_inc is not None and len(kept):
            inc[:, : kept_inc.shape[1]] = kept_inc
        if len(tri):
            # Column layout (3, ...): gathers and reductions along long rows are what numpy does fast.
            a, b = np.repeat(n, m, axis=0), np.tile(n, (m, 1))
            cross = np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],       # (3, m * m): n[a] x n[b]
                              a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                              a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]])
            i, j, k = tri[:, 0], tri[:, 1], tri[:, 2]
            cjk = np.take(cross, j * m + k, axis=1)
            det = (np.take(n.T, i, axis=1) * cjk).sum(axis=0)
            good = np.abs(det) > DET_MIN
            if not good.all():
                i, j, k, cjk, det = i[good], j[good], k[good], cjk[:, good], det[good]
            # Cramer's rule: x = (o_i (n_j x n_k) + o_j (n_k x n_i) + o_k (n_i x n_j)) / det.
            x = (o[i] * cjk + o[j] * np.take(cross, k * m + i, axis=1) + o[k] * np.take(cross, i * m + j, axis=1)) / det
            # Rounding error of the solve grows as the planes get closer to sharing a line;
            # it widens the feasibility test, and (capped, so an ill-conditioned point
            # cannot swallow distinct vertices) the merge and incidence reach.
            err = 16.0 * EPS * scale_o / np.abs(det)
            feasible = (n @ x - o[:, None]).max(axis=0) <= tol + err
            err = np.minimum(err, SNAP * tol)
            i, j, k, x, err = i[feasible], j[feasible], k[feasible], x[:, feasible].T, err[feasible]
            solved = np.zeros((len(x), m), dtype=bool)
            rows = np.arange(len(x))
            solved[rows, i] = solved[rows, j] = solved[rows, k] = True
            cand = np.concatenate([kept, x])
            radius = np.concatenate([radius, err])
            inc = np.concatenate([inc, solved])
        if len(cand) < 4:
            return None
        inc |= np.abs(cand @ n.T - o) <= (tight + radius)[:, None]
        # Duplicates (a vertex on more than three planes is solved several times) and
        # vertices closer than SNAP tol merge (plus their rounding-error bound), with
        # the planes of all of them.
        keep, group = _merge_groups(cand, SNAP * tol, radius)
        if len(keep) == len(cand):
            merged = inc[keep]
        else:
            member = np.zeros((len(keep), len(cand)), dtype=np.uint8)
            member[group, np.arange(len(cand))] = 1
            merged = (member @ inc.astype(np.uint8)) > 0
        return cls._finish(cand[keep] + 0.0, n, o, tol, merged)   # + 0.0: no negative zeros

    @classmethod
    def _finish(cls, verts: np.ndarray, n: np.ndarray, o: np.ndarray, tol: float, inc: np.ndarray | None = None):
        """The polytope of these vertices and planes: facets are the planes with
        three vertices or more, tidied at the tolerance's scale (see below)."""
        if inc is None:
            inc = np.abs(verts @ n.T - o) <= 4.0 * tol
        inc = inc.copy()
        m = len(n)
        near = coincident_planes(n, o, verts, COINCIDENT * tol)   # one plane over these vertices
        np.fill_diagonal(near, False)
        has_near = bool(near.any())
        rank = m - np.arange(m)                         # ties: the earlier (older) plane wins
        facet = np.ones(m, dtype=bool)
        for _ in range(4):
            if len(verts) < 4:
                return None
            count = inc.sum(axis=0)
            facet &= count >= 3
            incf = inc.astype(np.float64)
            shared = incf.T @ incf
            if has_near:
                # Nearly coincident planes meeting on the polytope are one facet (the
                # older plane's) with the vertices of both.
                for a, b in zip(*np.nonzero(np.triu(near & (shared >= 1) & np.outer(facet, facet), 1))):
                    if facet[a] and facet[b]:
                        inc[:, a] |= inc[:, b]
                        facet[b] = False
                count = inc.sum(axis=0)
                incf = inc.astype(np.float64)
                shared = incf.T @ incf
            # A facet whose vertices all lie on another facet is a sliver within the
            # tolerance (two true facets share at most an edge): drop it (of two equal
            # vertex sets, the later plane's).
            key = count * (m + 1) + rank
            facet &= ~((shared == count[None, :]) & (key[:, None] > key[None, :]) & facet[:, None]).any(axis=0)
            inc &= facet
            # A vertex left on fewer than three facets lies on a face (within the tolerance).
            corner = inc.sum(axis=1) >= 3
            if corner.all():
                break
            verts, inc = verts[corner], inc[corner]
        if facet.sum() < 4 or len(verts) < 4:
            return None
        n, o, inc = n[facet], o[facet], inc[:, facet]
        # No volume: every vertex on one facet plane.
        if np.any(inc.all(axis=0)):
            return None
        return cls(verts, n, o, inc, tol)

    # -- operations ----------------------------------------------------------
    def clip(self, normals, offsets) -> "ConvexPolytope | None":
        """This polytope ∩ {normals @ x <= offsets}; None when nothing with
        volume is left. Planes that cut nothing are ignored."""
        n2, o2 = _unit_rows(normals, offsets)
        if len(n2) == 0:
            return self
        d = self.vertices @ n2.T - o2
        if np.any(np.all(d >= -self.tol, axis=0)):
            return None
        cut = np.any(d > self.tol, axis=0)
        if not cut.any():
            return self
        n2, o2 = n2[cut], o2[cut]
        try:
            b = self.brep()
            for n, o in zip(n2.tolist(), o2.tolist()):
                b = _brep.cut(b, n, o, self.tol)
                if b is None:
                    return None
            return ConvexPolytope.from_brep(b, self.tol)
        except OpenCut:
            return self._clip_by_enumeration(n2, o2, d[:, cut])

    def _clip_by_enumeration(self, n2: np.ndarray, o2: np.ndarray, d: np.ndarray) -> "ConvexPolytope | None":
        """``clip`` by vertex enumeration, for half-spaces that all cut (``d``:
        the vertices' signed distances to them)."""
        n2, o2 = _dedupe_planes(n2, o2, self.tol, self.vertices)
        d = self.vertices @ n2.T - o2
        inside = np.all(d <= self.tol, axis=1)
        m = len(self.normals)
        n = np.concatenate([self.normals, n2])
        o = np.concatenate([self.offsets, o2])
        return type(self)._build(self.vertices[inside], n, o, _combinations3(len(n), m), self.tol,
                                 self.incidence[inside])

    def section(self, normals, offsets) -> np.ndarray | None:
        """Points whose convex hull is this polytope ∩ {normals @ x <= offsets}
        (every vertex of it among them, none outside it by more than the
        tolerance), or None when the half-spaces leave nothing of it. For when
        only the extent of a clip is needed: no faces are built.

        A vertex of the intersection is a vertex of P inside the half-spaces, or
        where an edge of P crosses one of their planes, or on the line where two
        of their planes meet, at an end of that line's stretch inside P and the
        other half-spaces; all three kinds are found at once."""
        n2, o2 = _unit_rows(normals, offsets)
        tol, v = self.tol, self.vertices
        d = v @ n2.T - o2                                          # (vertices, planes)
        if np.any(np.all(d >= -tol, axis=0)):
            return None
        if not np.any(d > tol):
            return v
        pts = [v[d.max(axis=1) <= tol]]
        edges = self.edges()
        da, db = d[edges[:, 0]], d[edges[:, 1]]
        e, p = np.nonzero(((da < -tol) & (db > tol)) | ((da > tol) & (db < -tol)))
        if len(e):
            t = da[e, p] / (da[e, p] - db[e, p])
            a = v[edges[e, 0]]
            x = a + t[:, None] * (v[edges[e, 1]] - a)
            pts.append(x[(x @ n2.T - o2).max(axis=1) <= tol])
        if len(n2) >= 2:
            i, j = _pairs(len(n2))
            c = np.einsum("ij,ij->i", n2[i], n2[j])
            u = cross_rows(n2[i], n2[j])
            keep = 1.0 - c * c > 1e-12                              # planes not parallel
            i, j, c, u = i[keep], j[keep], c[keep], u[keep]
            s = 1.0 - c * c
            base = (((o2[i] - o2[j] * c) / s)[:, None] * n2[i] + ((o2[j] - o2[i] * c) / s)[:, None] * n2[j])
            # The stretch t of base + t u inside P's facets and every half-space.
            an = np.concatenate([self.normals, n2])
            ao = np.concatenate([self.offsets, o2])
            rate = u @ an.T                                          # (lines, planes)
            room = ao - base @ an.T
            along = np.abs(rate) > 1e-12
            bound = room / np.where(along, rate, 1.0)
            t_hi = np.where(along & (rate > 0), bound, np.inf).min(axis=1)
            t_lo = np.where(along & (rate < 0), bound, -np.inf).max(axis=1)
            ok = (t_lo <= t_hi) & np.isfinite(t_lo) & np.isfinite(t_hi) & ~np.any(~along & (room < -tol), axis=1)
            if ok.any():
                pts.append(base[ok] + t_lo[ok, None] * u[ok])
                pts.append(base[ok] + t_hi[ok, None] * u[ok])
        pts = np.concatenate(pts)
        return pts if len(pts) else None

    def translated(self, offset) -> "ConvexPolytope":
        t = np.asarray(offset, dtype=np.float64)
        moved = ConvexPolytope(self.vertices + t, self.normals, self.offsets + self.normals @ t, self.incidence, self.tol,
                               self.loops)
        if "_edges" in self.__dict__:
            object.__setattr__(moved, "_edges", self.__dict__["_edges"])
        return moved

    def contains(self, points, tol: float | None = None) -> np.ndarray:
        t = 10.0 * self.tol if tol is None else tol
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        return (self.normals @ p.T - self.offsets[:, None]).max(axis=0, initial=-np.inf) <= t

    @property
    def centroid(self) -> np.ndarray:
        """Mean of the vertices (strictly inside for a polytope with volume)."""
        return self.vertices.mean(axis=0)

    @property
    def planes(self) -> list[Plane]:
        return [Plane(n, float(o)) for n, o in zip(self.normals, self.offsets)]

    def facet_loops(self) -> tuple:
        """Each facet's vertex indices, counter-clockwise seen from outside."""
        if self.loops is None:
            object.__setattr__(self, "loops", self._loops_from_incidence())
        return self.loops

    def _loops_from_incidence(self) -> tuple:
        """The facet loops of an enumerated polytope: each facet's vertices
        ordered by angle about its centre."""
        f, v = np.nonzero(self.incidence.T)
        counts = np.bincount(f, minlength=len(self.normals))
        pts = self.vertices[v]
        centre = np.stack([np.bincount(f, weights=pts[:, c], minlength=len(counts)) for c in range(3)], axis=1)
        centre /= np.maximum(counts, 1)[:, None]
        u = _perpendiculars(self.normals)
        w = cross_rows(self.normals, u)
        rel = pts - centre[f]
        ang = np.arctan2(np.einsum("ij,ij->i", rel, w[f]), np.einsum("ij,ij->i", rel, u[f]))
        order = np.lexsort((ang, f))
        ids = v[order].tolist()
        ends = np.cumsum(counts).tolist()
        return tuple(tuple(ids[e - c: e]) for e, c in zip(ends, counts.tolist()))

    def edges(self) -> np.ndarray:
        """(e, 2) vertex index pairs of the edges (lower index first, sorted):
        consecutive vertices of the facet loops. (From the loops rather than
        from shared planes, so a vertex lying on an edge within the tolerance
        splits it instead of making a triangle of "edges"; an edge of a loop
        left open is there once all the same.) Computed once per polytope
        (a read-only array; ``translated`` copies share it)."""
        cached = self.__dict__.get("_edges")
        if cached is None:
            cached = self._edges_from_loops()
            cached.flags.writeable = False
            object.__setattr__(self, "_edges", cached)
        return cached

    def _edges_from_loops(self) -> np.ndarray:
        keys = set()
        for loop in self.facet_loops():
            a = loop[-1]
            for c in loop:
                keys.add((a, c) if a < c else (c, a))
                a = c
        keys = sorted(keys)
        # (np.fromiter over the flat pairs: np.array on a list of tuples costs several times more.)
        return np.fromiter(chain.from_iterable(keys), np.int64, 2 * len(keys)).reshape(-1, 2)

    def faces(self) -> list[np.ndarray]:
        """The facets as (K, 3) vertex loops, counter-clockwise seen from outside,
        in facet order."""
        return [self.vertices[list(loop)] for loop in self.facet_loops()]


_HEX_QUADS = ((0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5))
_HEX_EDGES = ((0, 2, 3, 1, 4, 6, 7, 5, 0, 1, 2, 3), (2, 3, 1, 0, 6, 7, 5, 4, 4, 5, 6, 7))
"""The 12 edges (from, to) of a hexahedron with UNIT_CUBE_CORNERS ordering."""
_HEX_QUAD_INDEX = np.array(_HEX_QUADS)
_HEX_INCIDENCE = np.zeros((8, 6), dtype=bool)
_HEX_INCIDENCE[_HEX_QUAD_INDEX.T, np.arange(6)] = True
"""Which of the 6 quads (``_HEX_QUADS``) each of the 8 corners belongs to."""
_HEX_EDGE_INDEX = np.array(_HEX_EDGES)
_BOX_BITS = np.array([[(i >> 2) & 1, (i >> 1) & 1, i & 1] for i in range(8)], dtype=bool)
_BOX_NORMALS = np.concatenate([-np.eye(3), np.eye(3)])
_BOX_INCIDENCE = np.concatenate([~_BOX_BITS, _BOX_BITS], axis=1)
_BOX_LOOPS = ((0, 1, 3, 2), (0, 4, 5, 1), (0, 2, 6, 4), (4, 6, 7, 5), (2, 3, 7, 6), (1, 5, 7, 3))
"""The box's facet loops (-x, -y, -z, +x, +y, +z), counter-clockwise seen from outside."""
