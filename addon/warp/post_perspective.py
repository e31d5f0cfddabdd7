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

import numpy as np

from .body import IntersectionBody, view_frustum
from .fit import fit_keeping_points
from .frame import image_up
from .geometry import cross, normalize
from .light_hull import light_halfspaces
from .polyhedron import BOX_NORMALS, ConvexPolytope, Edges, box_edges, box_offsets, clip_segments, polytope_edges
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

OPTIMALITY_GAP = 1e-14
"""Wolfe's stopping test: x is taken as the hull's point nearest the origin when
x·x - min_p p·x <= this times the largest |p|² (0 exactly at the optimum)."""

NEAREST_BOX_CLIPS = 256
"""At most this many receiver boxes are measured against V ∩ L to find the
nearest visible depth; beyond that the remaining boxes' lower bound is used (safe)."""

NEAREST_BOX_BATCH = 8
"""Receiver boxes measured against V ∩ L at once, in order of their lower bound."""


# ---------------------------------------------------------------------------
# The virtual camera (§4.2, §6).
# ---------------------------------------------------------------------------

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


def virtual_camera(view: View, body: IntersectionBody, visible_near: float | None = None) -> VirtualCamera:
    """The shifted camera whose PPS PSM works in (module docstring; §4.2, §6).
    ``visible_near``: d_R (default: R's nearest depth, a safe lower bound)."""
    origin = view.position
    to_camera = view.world_to_camera[:3, :3]                # camera-relative world -> camera axes
    b_rel = body.vertices - origin
    b_depth = -(b_rel @ to_camera[2])
    if visible_near is None:
        visible_near = view.eye_depth(body.visible_vertices).min()
    d_r = float(max(visible_near, view.near))
    d_b = float(b_depth.min())
    shift = max(0.0, d_r - d_b)
    near = d_b + shift
    to_virtual_clip = np.zeros((4, 4))
    to_virtual_clip[:2, :3] = to_camera[:2]                 # x, y
    to_virtual_clip[2, 3] = -near                           # z = -near / depth_v: affine in 1 / depth
    to_virtual_clip[3, :3], to_virtual_clip[3, 3] = -to_camera[2], shift     # w = depth + shift, the virtual depth
    to_pps, b_in_pps = fit_keeping_points(to_virtual_clip, b_rel)          # (w >= near > 0 on B)
    return VirtualCamera(to_pps, shift, near, float(b_depth.max()) + shift, d_r, b_in_pps)


def nearest_visible_depth(view: View, light: Light, body: IntersectionBody,
                          options: WarpOptions | None = None) -> float:
    """The nearest eye depth at which a receiver can be seen (PSM §6's near
    plane "as far as possible"). A depth readback given as
    ``options.visible_depth_range`` wins; otherwise the least eye depth over
    the receiver boxes meeting V ∩ L of V ∩ L ∩ box (``lowest_in_boxes``),
    taking the boxes nearest bound first (``_BoxesByDepth``) and stopping
    when none left can be nearer. Always in [view.near, true nearest visible
    depth].

    No point of R = V ∩ S_r ∩ L is nearer than its nearest vertex (hence the
    lower bound ``coarse``, with the near plane), so when a receiver box about
    to be measured holds that vertex, the answer is ``coarse`` and the search
    stops without measuring: when the light's cone bounds R nearest the camera
    inside a building, or the near plane does inside a room's box."""
    if options is not None and options.visible_depth_range is not None:
        return max(float(options.visible_depth_range[0]), view.near)
    axis = -view.world_to_camera[2, :3]                     # camera-relative world -> eye depth
    depths = view.eye_depth(body.visible_vertices)
    nearest = body.visible_vertices[int(depths.argmin())] - view.position
    coarse = max(float(depths.min()), view.near)
    boxes = _BoxesByDepth(body.culled.receivers, axis, view.position, coarse)
    region, best, measured = None, math.inf, 0
    while (batch := boxes.next(NEAREST_BOX_BATCH, below=best)) is not None:
        lo, hi, bounds = batch
        if bounds[0] <= coarse and np.all((lo <= nearest) & (nearest <= hi), axis=1).any():
            return coarse                                    # R's nearest vertex is in a receiver box
        if region is None:
            region = _visible_region(view, light, body) or False
        depths = lowest_in_boxes(region, lo, hi, axis).tolist() if region else [math.inf] * len(bounds)
        for bound, depth in zip(bounds, depths):
            if bound >= best:
                break
            if measured >= NEAREST_BOX_CLIPS:                # the nearest box not measured is no nearer than this
                return max(min(best, bound, boxes.unopened), coarse)
            measured += 1
            best = min(best, depth)
    return max(best, coarse) if math.isfinite(best) else coarse


class _BoxesByDepth:
    """The receiver boxes a culling ``Selection`` holds, camera-relative, in
    order of a lower bound of their eye depth (the depth of the nearest
    corner, floored at ``floor``), drawn a batch at a time. Boxes come from
    the culling index's clusters, which have the same kind of bound: a
    cluster is opened (its boxes added to a pool kept in order) only when one
    of its boxes may be in the next batch."""

    def __init__(self, receivers, axis: np.ndarray, origin: np.ndarray, floor: float):
        self.index, self.picked = receivers.index, receivers.by_cluster
        # A box's bound: its nearest corner's depth, lo where the axis is positive, else hi (lo, -hi rows).
        self.nearest_corner = np.concatenate([np.maximum(axis, 0.0), np.maximum(-axis, 0.0)])
        self.shift, self.floor, self.origin = float(origin @ axis), floor, origin
        clusters = receivers.clusters
        c_lower = np.maximum((self.nearest_corner @ self.index.c_bounds)[clusters] - self.shift, floor)
        order = np.argsort(c_lower, kind="stable")
        self.clusters, self.c_lower = clusters[order], c_lower[order].tolist()
        self.opened = 0
        self.pool, self.pool_lower = np.zeros((6, 0)), np.zeros(0)

    @property
    def unopened(self) -> float:
        """The bound of the nearest cluster not opened yet (inf: none left)."""
        return self.c_lower[self.opened] if self.opened < len(self.clusters) else math.inf

    def _open(self, stop: int) -> None:
        """Add the boxes of clusters [opened, stop) to the pool, in order."""
        if stop <= self.opened:
            return
        ids = self.clusters[self.opened:stop]
        more = self.index.c_box_bounds[:, ids][:, self.picked[ids]]                 # (6, boxes): lo, -hi
        pool = np.concatenate([self.pool, more], axis=1)
        lower = np.concatenate([self.pool_lower, np.maximum(self.nearest_corner @ more - self.shift, self.floor)])
        order = np.argsort(lower, kind="stable")
        self.pool, self.pool_lower, self.opened = pool[:, order], lower[order], stop

    def next(self, count: int, below: float):
        """The nearest ``count`` boxes not drawn yet as (lo (K, 3), hi (K, 3),
        bounds), or None when no box left has a bound below ``below``. Every
        cluster that may hold one of them is opened first: enough for a full
        batch (each holds a box), then all whose bound is below the batch's
        farthest box."""
        reach = bisect.bisect_left(self.c_lower, below, self.opened)
        if len(self.pool_lower) < count and self.opened < reach:
            self._open(min(self.opened + count - len(self.pool_lower), reach))
        if len(self.pool_lower) >= count and self.opened < reach:
            self._open(bisect.bisect_left(self.c_lower, float(self.pool_lower[count - 1]), self.opened, reach))
        if not len(self.pool_lower) or min(float(self.pool_lower[0]), self.unopened) >= below:
            return None
        batch, bounds = self.pool[:, :count], self.pool_lower[:count].tolist()
        self.pool, self.pool_lower = self.pool[:, count:], self.pool_lower[count:]
        return batch[:3].T - self.origin, -batch[3:].T - self.origin, bounds


def lowest_in_boxes(region: ConvexPolytope, lo: np.ndarray, hi: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """min k·x over ``region`` ∩ [lo_i, hi_i] for each box i ((K, 3) corners,
    k = ``axis``), inf where they do not meet. A linear function is least at a
    vertex of region ∩ box, and every vertex ends an edge of one body clipped
    to the other (``polyhedron.section_points``): the region's edges clipped
    to each box and each box's edges clipped to the region, by Cyrus-Beck
    (exactly: no tolerance, which would move the nearest point along a surface
    seen at a grazing angle by the tolerance over the angle's sine). On a
    clipped edge k·x is least at the end it rises from."""
    return np.minimum(_lowest_on_edges(polytope_edges(region), BOX_NORMALS, box_offsets(lo, hi), axis),
                      _lowest_on_edges(box_edges(lo, hi), region.normals, region.offsets, axis))


def _lowest_on_edges(edges: Edges, normals: np.ndarray, offsets: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """min k·x over the edges clipped to the half-spaces, along the last axis (inf: nothing left)."""
    t_lo, t_hi = clip_segments(edges, normals, offsets)
    rise = edges.step @ axis
    least = edges.start @ axis + np.where(rise >= 0, t_lo, t_hi) * rise
    return np.where(t_lo <= t_hi, least, np.inf).min(axis=-1)


def _visible_region(view: View, light: Light, body: IntersectionBody) -> ConvexPolytope | None:
    """V ∩ L relative to the camera, or None when it is empty. V ∩ L ∩ box =
    R ∩ box for every receiver box (R = V ∩ S_r ∩ L, each box inside S_r), so
    B's R serves when it is relative to the camera too."""
    origin = view.position
    if body.origin.tolist() == origin.tolist():
        return body.visible_polytope
    ln, lo = light_halfspaces(light, origin)
    return view_frustum(view, origin, body.tolerance).clip(ln, lo)


# ---------------------------------------------------------------------------
# The light's cone in PPS (§3): the narrowest cone around B' seen from L'.
# ---------------------------------------------------------------------------

def min_norm_point(points, start=None, max_iter: int = 200) -> np.ndarray:
    """The point of the convex hull of ``points`` (M, d) nearest the origin,
    by Wolfe's algorithm (1976; exact up to rounding, finitely many steps).

    Wolfe keeps a support whose affine hull's nearest point x lies inside its
    convex hull. x is optimal when no point p has p·x < x·x (then every hull
    point y has |y|² >= |x|²); otherwise the point least along x joins the
    support and the support's affine nearest point is found (a minor cycle
    dropping any point whose weight would turn negative). It starts from the
    point nearest the origin, or from ``start``, indices of points whose
    affine nearest point has positive weights (two points of equal length:
    their midpoint)."""
    p = np.asarray(points, dtype=np.float64)
    square = np.einsum("ij,ij->i", p, p)
    scale = max(float(square.max()), 1e-300)
    support = list(start) if start is not None else [int(np.argmin(square))]
    weights = np.full(len(support), 1.0 / len(support))
    x = weights @ p[support]
    for _ in range(max_iter):
        dots = p @ x
        j = int(np.argmin(dots))
        if x @ x - dots[j] <= OPTIMALITY_GAP * scale or j in support:
            break
        support, weights = support + [j], np.append(weights, 0.0)
        for _ in range(max_iter):                    # the minor cycle
            alpha = _affine_min_norm(p[support])
            if alpha.min() > 1e-15:
                weights = alpha
                break
            falling = alpha <= 1e-15                 # move towards alpha until a weight reaches 0
            theta = np.min(weights[falling] / (weights[falling] - alpha[falling]))
            weights = theta * alpha + (1.0 - theta) * weights
            kept = weights > 1e-15
            support, weights = [s for s, k in zip(support, kept) if k], weights[kept] / weights[kept].sum()
        x = weights @ p[support]
    return x


def _affine_min_norm(q: np.ndarray) -> np.ndarray:
    """The weights α (Σ α_i = 1) of the point of the affine hull of the rows of
    ``q`` nearest the origin: the bordered system [Q Qᵀ 1; 1ᵀ 0] (α, μ) = (0, 1)
    (the stationary point of |Σ α_i q_i|² under the constraint), by least
    squares when the support is affinely dependent (the system singular)."""
    n = len(q)
    bordered = np.ones((n + 1, n + 1))
    bordered[:n, :n] = q @ q.T
    bordered[n, n] = 0.0
    rhs = np.zeros(n + 1)
    rhs[n] = 1.0
    try:
        solution = np.linalg.solve(bordered, rhs)
    except np.linalg.LinAlgError:
        solution = np.linalg.lstsq(bordered, rhs, rcond=None)[0]
    return solution[:n]


def smallest_cone(directions) -> tuple[np.ndarray, float]:
    """Axis k and margin min_i k·d_i of the narrowest cone around the unit
    ``directions``: k maximises min_i k·d_i, which by minimax duality is the
    direction of the hull's point nearest the origin (``min_norm_point``),
    and the margin is that point's norm (0 when the directions surround the
    origin). Wolfe starts from the most distant pair of directions (the least
    entry of their Gram matrix): most cones are spanned by two directions, and
    then the pair's midpoint is the answer at once."""
    d = np.asarray(directions, dtype=np.float64)
    i, j = divmod(int((d @ d.T).argmin()), len(d))
    x = min_norm_point(d, start=(i,) if i == j else (i, j))
    norm = math.sqrt(x @ x)
    if norm <= 1e-15:
        return np.array([0.0, 0.0, 1.0]), 0.0
    k = x / norm
    return k, float((d @ k).min())


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
    light = np.asarray(light_h, dtype=np.float64)
    light = light / math.sqrt(light @ light)
    l, w = light[:3], float(light[3])
    if abs(w) <= DIRECTIONAL_TOLERANCE * max(math.sqrt(l @ l), 1e-300):
        kind = "directional"
    else:
        kind = "point" if w > 0 else "inverted"
    b_in_pps = np.asarray(points, dtype=np.float64)
    rays = w * b_in_pps - l                                 # u(p), pointing away from the real light
    lengths = np.sqrt(np.einsum("ij,ij->i", rays, rays))
    if lengths.min() <= 1e-12 * max(float(lengths.max()), 1e-300):
        return PPSLight(None, light, kind, math.pi, np.array([0.0, 0.0, 1.0]), False)
    k, margin = smallest_cone(rays / lengths[:, None])
    half = math.acos(min(1.0, max(-1.0, margin)))
    if margin < MIN_CONE_MARGIN or half > max_half_angle:
        return PPSLight(None, light, kind, half, k, margin >= MIN_CONE_MARGIN)
    # The (a, b, k) frame centred at c, the mean of B'; (a, b, k) right-handed: the camera's
    # projection already reverses orientation, so the composed world -> light NDC map reverses it
    # once, like frame.FLIP_Z @ look_along (a uniform map): triangles facing the light keep their
    # winding (back-face biasing).
    centre = b_in_pps.sum(axis=0) / len(b_in_pps)
    b = image_up(PPS_VIEW_DIRECTION, PPS_UP, k)
    a = normalize(cross(b, k))
    axes = np.array([a, cross(k, a), k])
    frame = np.eye(4)
    frame[:3, :3], frame[:3, 3] = axes, -axes @ centre
    # L' in that frame, times w' (its depth is negative: c is a mean of B', every k·(w' p - l) > 0),
    # and the shear that makes the x, y and w rows vanish at L': they gain γx, γy and ρ times the depth row.
    lam = axes @ (l - w * centre)
    shear = np.array([-lam[0], -lam[1], 0.0, -w]) / lam[2]
    return PPSLight(frame + np.outer(shear, frame[2]), light, kind, half, k)
