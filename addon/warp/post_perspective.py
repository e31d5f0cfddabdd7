"""Post-perspective space (PPS) of a virtual camera and light frusta inside it
(Stamminger & Drettakis, *Perspective Shadow Maps*, §2-§4). Numpy only.

**The virtual camera (§4.2, §6).** PSM renders the shadow map in the camera's
post-perspective space. The paper moves the camera back along its view
direction ("virtual camera shift") until the body H (our B) lies entirely in
front of its near plane, keeping the near distance unchanged (§4.2), and wants
that near plane as far away as possible: it reads back the depth buffer to put
it at the nearest visible depth (§6). Lixel combines the two. ``d_R`` is the
nearest visible depth (:func:`nearest_visible_depth`): the caller's depth
readback ``WarpOptions.visible_depth_range`` when given, else the nearest point
of V ∩ L ∩ (a receiver box), which is never nearer than the camera's near
distance and never farther than what is really visible. B's nearest eye depth
is ``d_B <= d_R`` (casters between the camera and R, or behind the camera).
The virtual eye moves back by

    s = d_R - d_B  >= 0,

so B's nearest point is as far from the virtual eye as the nearest visible
point is from the real one. s is 0 when nothing in B is nearer than R, and
continuous in the configuration. Only the eye position and the view direction
(the camera plane) shape PPS; the field of view, lens shift and near/far only
apply an affine map to PPS. So the virtual projection is the plain perspective
(x, y, -n_v, depth_v) with n_v = d_R, then fitted (``fit.fit_to_unit_cube``)
so that B's PPS image B' fills the unit cube [-1, 1]^3: the virtual near plane
is at B's nearest point, the far plane at B's farthest point. That keeps PPS
well conditioned whatever the camera's own clip range (1e-3 .. 1e4).

**The light in PPS (§3).** The light in homogeneous coordinates (w = 0 for a
sun) is mapped by the virtual camera: L' = (l, w'). w' > 0: a point light in
PPS; w' < 0 (the light behind the camera plane): an *inverted* point light whose
rays converge (§3.1-§3.2; the order of points along a ray reverses); w' = 0 (a
sun perpendicular to the view, a point light in the camera plane): a
directional light in PPS.

**One formula for all three (:func:`pps_light_matrix`).** For a PPS point p,
the oriented ray direction u(p) = w' p - l is finite and continuous in w'; it
points from L' to p when w' > 0, from p to L' when w' < 0 and along -l (the
light's travel direction) when w' = 0. In every case the real light lies on the
-u side (moving from p towards the real light changes p by +t·(l - w' p)). The
map's depth axis k is the axis of the smallest cone containing all u(B'), and

    x = (a·q + γx k·q) / (1 + ρ k·q),  y = (b·q + γy k·q) / (1 + ρ k·q),
    z = k·q / (1 + ρ k·q),             q = p - c,

with c the mean of B' (inside B'), a, b ⊥ k, and γ, ρ chosen so the x, y and w
rows vanish at L' (rays through L' collapse to one texel). That is the
central projection from L' onto the plane through c perpendicular to k,
measured along a, b, for any w'; ρ ∝ w' and at w' = 0 it is the orthographic
projection along l. Depth increases along k, i.e. away from the real light
for normal, inverted and directional PPS lights alike, so the depth test is
always LESS: the paper's inverted light with a reversed depth *test* (§3.1) is
here an inverted depth *axis*, the same map up to z -> -z, and the map stays
continuous when the light crosses the camera plane (PPS light through
infinity). w = 1 + ρ k·q > 0 on B' exactly when the cone is narrower than
180°, i.e. when a plane through L' has B' strictly on one side: always for a
sun (B' lies strictly before the PPS image of infinity), and for a point light
outside B.
"""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from operator import mul

import numpy as np

from .body import IntersectionBody
from .light_hull import light_halfspaces
from .fit import fit_keeping_points
from .frame import image_up
from .geometry import cross3, normalize
from .polyhedron import ConvexPolytope, float_rows
from .types import Light, View, WarpOptions

PPS_VIEW_DIRECTION = np.array([0.0, 0.0, 1.0])
"""The view direction in PPS (NDC z grows with eye depth)."""
PPS_UP = np.array([0.0, 1.0, 0.0])

MIN_CONE_MARGIN = 1e-9
"""Smallest accepted min_i k·u_i (cosine of the cone's half-angle): below it
the light is (numerically) on or inside B' and one frustum cannot cover B'."""

DIRECTIONAL_TOLERANCE = 1e-12
"""|w'| / |l| below which the PPS light is reported as directional (the matrix
itself needs no threshold: it is continuous through w' = 0)."""


@dataclass(frozen=True)
class VirtualCamera:
    """``to_pps``: camera-relative world (p - eye) -> PPS clip, with B' filling
    [-1, 1]^3 and w = virtual eye depth > 0 on B. ``shift``: how far the virtual
    eye sits behind the real one; ``near``/``far``: B's nearest/farthest virtual
    eye depth; ``visible_near``: d_R, the nearest visible eye depth; ``points``:
    B' (B's vertices in PPS, divided)."""

    to_pps: np.ndarray
    shift: float
    near: float
    far: float
    visible_near: float
    points: np.ndarray


NEAREST_BOX_CLIPS = 256
"""At most this many receiver boxes are measured against V ∩ L to find the
nearest visible depth; beyond that the remaining boxes' lower bound is used (safe)."""

NEAREST_BOX_BATCH = 8
"""Receiver boxes measured against V ∩ L at once (vectorised), in order of their lower bound."""


_BOX_CORNER_BITS = np.array([[i >> 2 & 1, i >> 1 & 1, i & 1] for i in range(8)], dtype=bool).T[:, :, None]
"""A box's 8 corners, (3, 8, 1): coordinate c of corner i is hi where bit (2 - c) of i is set, else lo."""
_BOX_EDGE_FROM = np.array([[i for i in range(8) if not i & bit] for bit in (4, 2, 1)])
"""A box's 12 edges, (3, 4): the corners the 4 edges along x, y and z start from (towards hi)."""


class LowestInBoxes:
    """min k·x over a convex region ∩ [lo_i, hi_i] for each box i of a batch,
    inf where they do not meet; the region (``vertices``, facets n·x <= o and
    their ``loops``) and k (``axis``) are prepared once, the boxes given per
    call (``__call__(lo, hi)``, (K, 3) corners).

    A linear function is least at a vertex of region ∩ box, and each such
    vertex (on three of their planes) ends a region edge clipped by the box (a
    region vertex in the box, or a region edge through a box face) or a box
    edge clipped by the region (a box corner in the region, or a box edge
    through a region facet). So clipping both edge sets gives the least value
    without building the intersection; on each clipped edge k·x is least at
    the end k rises from.

    * Box edges by the region's facets (Cyrus-Beck): the edge from corner c
      along axis j, x = c + t e_j, t ∈ [0, s_j] (s_j >= 0, the box's size),
      stays in facet h while t n_hj <= o_h - n_h·c, so the facets with
      n_hj < 0 bound t from below and the others from above, whatever the
      box, and the ratios do not depend on the box's size (a flat box's edge,
      s_j = 0, is the point t = 0). A zero n_hj (an edge parallel to the
      facet) makes the ratio +inf (keeps the edge) or -inf (drops it) on the
      side it is counted on, or NaN (0/0: the edge lies in the facet's plane,
      kept) which fmax and fmin skip; the normals' zeros are made +0 so that
      such a facet counts as bounding from above with a +0 denominator. A
      nearly parallel facet overflows to the same ±inf limits.
    * The region's edges by the box (slabs): x = p - λ (p - q) for the facet
      loops' consecutive vertices p, q (each edge twice, once per facet, so a
      vertex splitting an edge within the tolerance loses nothing). In
      coordinate j, λ lies between (p_j - lo_j) / e_j and (p_j - hi_j) / e_j
      (e = p - q): the smaller bounds it from below, the larger from above,
      whatever the sign of e_j. e_j = 0 gives -inf and +inf (inside the slab:
      no bound), two equal infinities (outside: empty) or, for p on a face,
      NaN, which minimum and maximum pass on and fmax and fmin skip (the edge
      lies in the face's plane: kept)."""

    def __init__(self, vertices: np.ndarray, normals: np.ndarray, offsets: np.ndarray, loops, axis: np.ndarray):
        # Each loop's edges (p, q): its vertices after their predecessors, both ends gathered
        # at once as columns (numpy broadcasts over a transposed view about twice as slowly).
        ends = [v for loop in loops for v in loop[-1:] + loop[:-1]]
        count = len(ends)
        ends += [v for loop in loops for v in loop]
        pq = vertices.T[:, ends]                                        # (3, 2E): p, then q
        p = pq[:, :count]
        e = p - pq[:, count:]
        self._p, self._e = p[:, None, :], e[:, None, :]                 # (3, 1, E)
        self._p_depth, self._e_depth = axis @ p, axis @ e               # k·x = p·k - λ e·k
        self._e_falls = self._e_depth <= 0                              # k rises from the entering end
        n = normals + 0.0                                               # no -0 components
        self._to_facets_and_axis = np.concatenate([n, axis[None]])      # (m + 1, 3)
        self._n = n[:, :, None, None]                                   # (m, 3, 1, 1)
        self._from_below = self._n < 0
        self._from_above = ~self._from_below
        self._o = offsets[:, None, None, None]
        self._axis = axis[:, None, None]                                # (3, 1, 1)
        self._axis_rises = self._axis >= 0

    @classmethod
    def of(cls, region: ConvexPolytope, axis: np.ndarray) -> "LowestInBoxes":
        return cls(region.vertices, region.normals, region.offsets, region.facet_loops(), axis)

    def __call__(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        # As (3, K) columns, contiguous (free when given as the transpose of contiguous columns).
        lo, hi = np.ascontiguousarray(lo.T), np.ascontiguousarray(hi.T)
        m, count = len(self._o), lo.shape[1]
        with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
            # Box edges clipped by the region's facets, as t = λ s_j (the distance along
            # the edge, in [0, s_j]): (m, 3, 4, K). Every facet's n·x and k·x at the boxes'
            # corners in one product, then read at each edge's first corner.
            corners = np.where(_BOX_CORNER_BITS, hi[:, None, :], lo[:, None, :]).reshape(3, -1)
            start = (self._to_facets_and_axis @ corners).reshape(m + 1, 8, count)[:, _BOX_EDGE_FROM]
            size = (hi - lo)[:, None, :]
            ratio = (self._o - start[:m]) / self._n
            enter = np.fmax.reduce(ratio, axis=0, where=self._from_below, initial=0.0)
            leave = np.fmin(np.fmin.reduce(ratio, axis=0, where=self._from_above, initial=np.inf), size)
            value = start[m] + np.where(self._axis_rises, enter, leave) * self._axis
            box_edges = np.where(enter <= leave, value, np.inf).min(axis=(0, 1))
            # The region's edges clipped by the boxes' slabs: (3, K, E).
            to_lo, to_hi = (self._p - lo[:, :, None]) / self._e, (self._p - hi[:, :, None]) / self._e
            lower, upper = np.minimum(to_lo, to_hi), np.maximum(to_lo, to_hi)
            enter = np.fmax.reduce(lower, axis=0, initial=0.0)
            leave = np.fmin.reduce(upper, axis=0, initial=1.0)
            value = self._p_depth - np.where(self._e_falls, enter, leave) * self._e_depth
            region_edges = np.where(enter <= leave, value, np.inf).min(axis=1)
        return np.minimum(box_edges, region_edges)


def lowest_in_boxes(region: ConvexPolytope, lo: np.ndarray, hi: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """min k·x over ``region`` ∩ [lo_i, hi_i] for each box i ((K, 3) corners,
    k = ``axis``); inf where they do not meet (``LowestInBoxes``)."""
    return LowestInBoxes.of(region, axis)(lo, hi)


def nearest_visible_depth(view: View, light: Light, body: IntersectionBody,
                          options: WarpOptions | None = None) -> float:
    """The nearest eye depth at which a receiver can be seen (PSM §6's near
    plane "as far as possible"). A depth readback given as
    ``options.visible_depth_range`` wins; otherwise the minimum over the
    receiver boxes meeting V ∩ L of the nearest point of V ∩ L ∩ box
    (``LowestInBoxes``), visiting the culling index's clusters and then
    their boxes by a lower bound (the nearest corner of their bounds) and
    stopping when none can be nearer, so only the boxes near the camera are
    touched. Always in [view.near, true nearest visible depth].

    No point of R = V ∩ S_r ∩ L is nearer than its nearest vertex (hence the
    lower bound ``coarse``, with the near plane), so when a receiver box about
    to be measured holds that vertex, the answer is ``coarse`` and the search
    stops without measuring: when the light's cone bounds R nearest the camera
    inside a building, or the near plane does inside a room's box."""
    if options is not None and options.visible_depth_range is not None:
        return max(float(options.visible_depth_range[0]), view.near)
    origin = view.position
    axis = -view.world_to_camera[2, :3]            # camera-relative world -> eye depth
    depths = (body.visible_vertices - origin) @ axis
    first = int(depths.argmin())
    coarse = max(float(depths[first]), view.near)
    index, picked = body.receivers.index, body.receivers.by_cluster
    clusters = body.receivers.clusters            # the clusters holding picked boxes
    if not len(clusters):
        return coarse
    # A box's lower bound: the depth of the nearest corner of its bounds (lo, -hi), per
    # coordinate lo where the axis is positive, else hi; the clusters' likewise.
    o, k = origin.tolist(), axis.tolist()
    nearest = np.array([max(c, 0.0) for c in k] + [max(-c, 0.0) for c in k])
    shift = _dot(o, k)
    c_lower = np.maximum((nearest @ index.c_bounds)[clusters] - shift, coarse)
    order = np.argsort(c_lower, kind="stable")
    clusters, c_lower = clusters[order], c_lower[order].tolist()   # nearest bound first
    # A box holds R's nearest vertex when its bounds (lo, -hi) are all at most these.
    v = body.visible_vertices[first].tolist()
    holding_nearest = np.array(v + [-c for c in v])[:, None]
    corner_origin = np.array(o + [-c for c in o])[:, None]
    lowest = None                                  # R's edges and facets, prepared for the first batch
    # Boxes are drawn from the clusters into a pool kept in the order of their bounds,
    # and examined NEAREST_BOX_BATCH at a time from its front (the batch is the nearest
    # of all boxes not yet examined), until no pending box (in the pool or in a cluster
    # not yet opened) can be nearer than the best found.
    opened = 0
    pool_bounds, pool_lower = np.zeros((6, 0)), np.zeros(0)
    best = math.inf
    count = 0

    def open_until(stop: int) -> None:
        """Add the boxes of clusters [opened, stop) to the pool, in one pass."""
        nonlocal opened, pool_bounds, pool_lower
        if stop <= opened:
            return
        ids = clusters[opened:stop]
        more = index.c_box_bounds[:, ids][:, picked[ids]]                # (6, boxes): lo, -hi
        lower = np.maximum(nearest @ more - shift, coarse)
        if len(pool_lower):
            more, lower = np.concatenate([pool_bounds, more], axis=1), np.concatenate([pool_lower, lower])
        order = np.argsort(lower, kind="stable")
        pool_bounds, pool_lower, opened = more[:, order], lower[order], stop

    while True:
        # Open every cluster that may hold one of the next batch's boxes: first enough
        # for a full batch (each holds at least one box), then all whose bound is below
        # the batch's farthest box.
        reach = bisect.bisect_left(c_lower, best, opened)               # clusters that can beat best
        missing = NEAREST_BOX_BATCH - len(pool_lower)
        if missing > 0 and opened < reach:
            open_until(min(opened + missing, reach))
        if len(pool_lower) >= NEAREST_BOX_BATCH and opened < reach:
            open_until(bisect.bisect_left(c_lower, float(pool_lower[NEAREST_BOX_BATCH - 1]), opened, reach))
        unopened = c_lower[opened] if opened < len(clusters) else math.inf
        if not len(pool_lower) or min(float(pool_lower[0]), unopened) >= best:
            break
        bounds, lower = pool_bounds[:, :NEAREST_BOX_BATCH], pool_lower[:NEAREST_BOX_BATCH].tolist()
        # Only a box whose bound is ``coarse`` can hold R's nearest vertex (its nearest
        # corner is no farther), and the batch starts with the least bound.
        if lower[0] <= coarse and (bounds <= holding_nearest).all(axis=0).any():
            best = coarse                          # R's nearest vertex is in a receiver box
            break
        if lowest is None:
            lowest = _lowest_in_visible_region(view, light, body, axis)
        rel = bounds - corner_origin                                    # (6, K): lo, -hi camera-relative
        depths = lowest(rel[:3].T, (-rel[3:]).T).tolist()
        for bound, depth in zip(lower, depths):
            if bound >= best:
                break
            if count >= NEAREST_BOX_CLIPS:                # the nearest unvisited box is no nearer than this
                return max(min(best, bound, unopened), coarse)
            count += 1
            best = min(best, depth)
        pool_bounds, pool_lower = pool_bounds[:, NEAREST_BOX_BATCH:], pool_lower[NEAREST_BOX_BATCH:]
    if not math.isfinite(best):
        return coarse
    return max(best, coarse)


def _lowest_in_visible_region(view: View, light: Light, body: IntersectionBody, axis: np.ndarray):
    """``LowestInBoxes`` over V ∩ L, camera-relative (all inf when it is empty).
    V ∩ L ∩ box = R ∩ box for every receiver box (R = V ∩ S_r ∩ L, each box
    inside S_r), so R's boundary serves when B has kept it."""
    origin = view.position
    b = body.visible_boundary
    if b is not None and body.origin.tolist() == origin.tolist():
        return LowestInBoxes(float_rows(b.vertices), float_rows(b.normals), np.array(b.offsets), b.loops, axis)
    ln, lo = light_halfspaces(light, origin)
    region = ConvexPolytope.from_corners(view.corners() - origin, body.tolerance).clip(ln, lo)
    if region is None:
        return _NoRegion()
    return LowestInBoxes.of(region, axis)


class _NoRegion:
    """``LowestInBoxes`` over an empty region: no box meets it."""

    def __call__(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        return np.full(len(lo), np.inf)


def virtual_camera(view: View, body: IntersectionBody, visible_near: float | None = None) -> VirtualCamera:
    """The shifted camera whose PPS PSM works in (module docstring; §4.2, §6).
    ``visible_near``: d_R (default: R's nearest depth, a safe lower bound)."""
    origin = view.position
    to_cam = view.world_to_camera[:3, :3]          # camera-relative world -> camera axes
    rel = body.vertices - origin
    depth = -(rel @ to_cam[2])
    if visible_near is None:
        visible_near = (-((body.visible_vertices - origin) @ to_cam[2])).min()
    d_r = float(max(visible_near, view.near))
    d_b = float(depth.min())
    shift = max(0.0, d_r - d_b)
    near = d_b + shift
    (x0, x1, x2), (y0, y1, y2), (z0, z1, z2) = to_cam.tolist()
    raw = np.array([[x0, x1, x2, 0.0],
                    [y0, y1, y2, 0.0],
                    [0.0, 0.0, 0.0, -near],      # z_pps = -near / depth_v: affine in 1/depth (perspective depth)
                    [-z0, -z1, -z2, shift]])     # w = depth + shift = virtual eye depth
    to_pps, points = fit_keeping_points(raw, rel)          # (w >= near > 0 on B)
    return VirtualCamera(to_pps, shift, near, float(depth.max()) + shift, d_r, points)


OPTIMALITY_GAP = 1e-14
"""Wolfe's stopping test: x is taken as the hull's point nearest the origin when
x·x - min_p p·x <= this times the largest |p|² (0 exactly at the optimum)."""

AFFINE_DEPENDENCE = 1e-14
"""Relative size of a pivot (or of the 2x2 determinant) below which Wolfe's
support counts as affinely dependent and is solved by least squares."""


def _dot(u, v) -> float:
    """u·v for plain float sequences."""
    return sum(map(mul, u, v))


def _affine_min_norm(q: list) -> list | None:
    """Weights α (Σ α_i = 1) of the point of the affine hull of ``q`` (plain
    float vectors) nearest the origin, or None when ``q`` is affinely dependent.
    x = q_0 + Σ_i β_i e_i with e_i = q_i - q_0 is nearest when x ⊥ every e_i:
    the normal equations Σ_j (e_i·e_j) β_j = -e_i·q_0, solved in closed form
    for one or two unknowns (Wolfe's usual supports) and by Gaussian
    elimination beyond."""
    q0 = q[0]
    e = [[a - b for a, b in zip(qi, q0)] for qi in q[1:]]
    m = len(e)
    if m == 0:
        return [1.0]
    gram = [[_dot(ei, ej) for ej in e] for ei in e]
    rhs = [-_dot(ei, q0) for ei in e]
    least = AFFINE_DEPENDENCE * max(gram[i][i] for i in range(m)) ** m
    if m == 1:
        if gram[0][0] <= least:
            return None
        beta = [rhs[0] / gram[0][0]]
    elif m == 2:
        (g00, g01), (_, g11) = gram
        det = g00 * g11 - g01 * g01
        if det <= least:
            return None
        beta = [(rhs[0] * g11 - rhs[1] * g01) / det, (g00 * rhs[1] - g01 * rhs[0]) / det]
    else:
        beta = _solve(gram, rhs, AFFINE_DEPENDENCE * max(gram[i][i] for i in range(m)))
        if beta is None:
            return None
    return [1.0 - sum(beta)] + beta


def _solve(a: list, b: list, least: float) -> list | None:
    """x with a x = b (plain float lists), Gaussian elimination with partial
    pivoting; None when a pivot is at most ``least``."""
    m = len(b)
    rows = [list(r) + [v] for r, v in zip(a, b)]
    for c in range(m):
        p = max(range(c, m), key=lambda r: abs(rows[r][c]))
        if abs(rows[p][c]) <= least:
            return None
        rows[c], rows[p] = rows[p], rows[c]
        for r in range(c + 1, m):
            f = rows[r][c] / rows[c][c]
            rows[r] = [u - f * v for u, v in zip(rows[r], rows[c])]
    x = [0.0] * m
    for c in reversed(range(m)):
        x[c] = (rows[c][m] - _dot(rows[c][c + 1:m], x[c + 1:])) / rows[c][c]
    return x


def _bordered_lstsq(q: list) -> list:
    """The affine weights of ``_affine_min_norm`` for an affinely dependent
    ``q``: the least-squares solution of the bordered system [Q Qᵀ 1; 1ᵀ 0]."""
    n = len(q)
    a = np.ones((n + 1, n + 1))
    a[:n, :n] = [[_dot(u, v) for v in q] for u in q]
    a[n, n] = 0.0
    rhs = np.zeros(n + 1)
    rhs[n] = 1.0
    return np.linalg.lstsq(a, rhs, rcond=None)[0][:n].tolist()


def _combination(weights, q) -> list:
    """Σ_i weights_i q_i for plain float vectors."""
    return [_dot(weights, column) for column in zip(*q)]


def min_norm_point(points, max_iter: int = 200) -> np.ndarray:
    """The point of the convex hull of ``points`` (M, d) nearest the origin
    (Wolfe's algorithm, 1976: exact up to rounding, finitely many steps). The
    support has at most d + 1 points, so its affine solves run on plain floats
    (``_affine_min_norm``)."""
    p = np.asarray(points, dtype=np.float64)
    rows = p.tolist()
    sq = np.einsum("ij,ij->i", p, p)
    scale = max(float(sq.max()), 1e-300)
    support = [int(np.argmin(sq))]
    weights = [1.0]
    x = rows[support[0]]
    for _ in range(max_iter):
        dots = p @ x
        j = int(np.argmin(dots))
        if _dot(x, x) - float(dots[j]) <= OPTIMALITY_GAP * scale or j in support:
            break
        support.append(j)
        weights.append(0.0)
        for _ in range(max_iter):
            q = [rows[s] for s in support]
            alpha = _affine_min_norm(q)
            if alpha is None:                              # affinely dependent support
                alpha = _bordered_lstsq(q)
            if min(alpha) > 1e-15:
                weights = alpha
                x = _combination(alpha, q)
                break
            theta = min(w / (w - a) for w, a in zip(weights, alpha) if a <= 1e-15)
            weights = [theta * a + (1.0 - theta) * w for a, w in zip(alpha, weights)]
            kept = [(s, w) for s, w in zip(support, weights) if w > 1e-15]
            support = [s for s, _ in kept]
            total = sum(w for _, w in kept)
            weights = [w / total for _, w in kept]
            x = _combination(weights, [rows[s] for s in support])
    return np.array(x)


def smallest_cone(directions) -> tuple[np.ndarray, float]:
    """Axis k and margin min_i k·d_i of the narrowest cone around the unit
    ``directions``: k maximises min_i k·d_i, which by minimax duality is the
    direction of the hull's point nearest the origin, and the margin is that
    point's norm (0 when the directions surround the origin).

    Most cones are spanned by two directions (``two_point_cone_centre``); the
    hull's nearest point is then found with one Gram product, and Wolfe's
    iteration (``min_norm_point``) runs only when that test fails."""
    d = np.asarray(directions, dtype=np.float64)
    x = two_point_cone_centre(d)
    return cone_through(min_norm_point(d).tolist() if x is None else x, d)


def cone_through(x: list, directions: np.ndarray) -> tuple[np.ndarray, float]:
    """The cone around the unit ``directions`` whose axis points at the hull
    point ``x`` (plain floats), and its margin min_i k·d_i (0 when x is the
    origin: the directions surround it)."""
    norm = math.sqrt(_dot(x, x))
    if norm <= 1e-15:
        return np.array([0.0, 0.0, 1.0]), 0.0
    k = np.array([c / norm for c in x])
    return k, float((directions @ k).min())


def two_point_cone_centre(directions: np.ndarray) -> list | None:
    """The hull's point nearest the origin (plain floats) when the narrowest
    cone around the unit ``directions`` is spanned by two of them, else None.

    Wolfe's optimality condition: a point x of the hull is the nearest to the
    origin iff p·x >= x·x for every point p. (If so, every hull point y has
    y·x >= x·x, and |y|² = |x|² + 2 x·(y - x) + |y - x|² >= |x|²; conversely,
    a p with p·x < x·x gives nearer points on the segment from x to p.)
    A two-point cone of half-angle θ has the midpoint x = (d_i + d_j) / 2 of
    its two spanning directions as that point (the nearest point of the
    segment between two unit vectors is its midpoint), d_i and d_j lie 2θ
    apart, and no two directions lie further apart than 2θ (both are within
    θ of the axis). So the candidate is the midpoint of a most distant pair,
    the least entry of the Gram matrix G = D Dᵀ, and the test needs only
    p·x = (G_pi + G_pj) / 2, with x·x = (x·d_i + x·d_j) / 2. The test allows
    the gap Wolfe's own stopping test allows (``OPTIMALITY_GAP``), so it
    accepts exactly the points ``min_norm_point`` would stop at. When the
    cone needs three directions the midpoint is not the nearest point and
    fails the test (by more than the gap, unless a third direction lies on
    the pair's cone to within it)."""
    gram = directions @ directions.T
    i, j = divmod(int(gram.argmin()), len(directions))
    dots = gram[i] + gram[j]                            # 2 p·x for every direction p
    if (float(dots[i]) + float(dots[j])) / 4 - float(dots.min()) / 2 > OPTIMALITY_GAP:
        return None
    return [(a + b) / 2 for a, b in zip(directions[i].tolist(), directions[j].tolist())]


@dataclass(frozen=True)
class PPSLight:
    """The light's frustum in PPS. ``matrix``: PPS -> light clip before the
    unit-cube fit (None if no single frustum covers B', or if the cone is wider
    than the caller allowed); ``light``: L' = (l, w') normalised to unit length;
    ``kind``: "point", "inverted" or "directional"; ``cone_half_angle``:
    radians; ``axis``: k; ``single_frustum``: whether a frustum from L' can hold
    B' (its cone is narrower than 180°)."""

    matrix: np.ndarray | None
    light: np.ndarray
    kind: str
    cone_half_angle: float
    axis: np.ndarray
    single_frustum: bool = True

    @property
    def position(self) -> np.ndarray | None:
        """L' as a PPS point, None when it is at infinity (directional)."""
        if self.kind == "directional":
            return None
        return self.light[:3] / self.light[3]


def pps_light_matrix(light_h, points, max_half_angle: float = math.inf) -> PPSLight:
    """The light frustum from the homogeneous PPS light ``light_h`` over the
    PPS points ``points`` (B'), see the module docstring; its matrix is not
    built when the cone's half-angle exceeds ``max_half_angle`` (the caller
    hands over to another map)."""
    lh = np.asarray(light_h, dtype=np.float64)
    lx, ly, lz, lw = lh.tolist()
    size = math.sqrt(lx * lx + ly * ly + lz * lz + lw * lw)
    lh = lh / size
    l, wp = lh[:3], lw / size
    if abs(lw) <= DIRECTIONAL_TOLERANCE * max(math.sqrt(lx * lx + ly * ly + lz * lz), 1e-300 * size):
        kind = "directional"
    else:
        kind = "point" if wp > 0 else "inverted"
    pts = np.asarray(points, dtype=np.float64)
    rays = wp * pts - l
    lengths = np.sqrt(np.einsum("ij,ij->i", rays, rays))
    if lengths.min() <= 1e-12 * max(float(lengths.max()), 1e-300):
        return PPSLight(None, lh, kind, math.pi, np.array([0.0, 0.0, 1.0]), False)
    k, margin = smallest_cone(rays / lengths[:, None])
    half = math.acos(min(1.0, max(-1.0, margin)))
    if margin < MIN_CONE_MARGIN or half > max_half_angle:
        return PPSLight(None, lh, kind, half, k, margin >= MIN_CONE_MARGIN)
    centre = (pts.sum(axis=0) / len(pts)).tolist()   # c, the mean of B'
    b = image_up(PPS_VIEW_DIRECTION, PPS_UP, k)
    # (a, b, k) right-handed: the camera's projection already reverses orientation, so
    # the composed world -> light NDC map reverses it once, like frame.FLIP_Z @ look_along
    # (a uniform map): triangles facing the light keep their winding (back-face biasing).
    a = normalize(cross3(b, k))
    axes = [a.tolist(), cross3(k, a).tolist(), k.tolist()]
    frame = [[*e, -_dot(e, centre)] for e in axes]   # the (a, b, k) frame centred at c
    frame.append([0.0, 0.0, 0.0, 1.0])
    light_from_centre = [li - wp * ci for li, ci in zip(l.tolist(), centre)]   # l - w' c
    lam = [_dot(e, light_from_centre) for e in axes]   # L' in that frame, times w'
    # lam[2] = -k·(w' c - l) < 0: c is a mean of B', every k·(w' p - l) > 0.
    gx, gy, rho = -lam[0] / lam[2], -lam[1] / lam[2], -wp / lam[2]
    # The shear: the x, y and w rows gain γx, γy and ρ times the depth row, so they vanish at L'.
    depth = frame[2]
    m = np.array([[f + g * z for f, z in zip(row, depth)] for row, g in zip(frame, (gx, gy, 0.0, rho))])
    return PPSLight(m, lh, kind, half, k)
