"""Post-perspective space (PPS) and the light's frustum in it (Stamminger & Drettakis, *Perspective Shadow
Maps*, §3-§4, §6): the virtual camera and one frustum for point, inverted and directional lights L'.
Its formulas: docs/papers.md, "The warp core's derivations"."""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np

from .body import IntersectionBody
from .fit import divided, window_matrix
from .frame import image_up
from .geometry import cross, normalize
from .polyhedron import BOX_NORMALS, ConvexPolytope, Edges, box_edges, box_offsets, clip_segments
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
    """``to_pps``: camera-relative world -> PPS clip, B' filling [-1, 1]^3; ``shift``: s;
    ``near``/``far``: B's virtual eye depths; ``visible_near``: d_R; ``points``: B'."""

    to_pps: np.ndarray
    shift: float
    near: float
    far: float
    visible_near: float
    points: np.ndarray


def virtual_camera(view: View, body: IntersectionBody, visible_near: float | None = None) -> VirtualCamera:
    """The shifted camera of §4.2 and §6; ``visible_near``: d_R (default: R's nearest depth)."""
    to_camera = view.world_to_camera[:3, :3]                # camera-relative world -> camera axes
    b_rel = body.vertices - view.position
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
    ndc = divided(b_rel @ to_virtual_clip[:, :3].T + to_virtual_clip[:, 3])      # (w >= near > 0 on B)
    window = window_matrix(ndc.min(axis=0), ndc.max(axis=0))                  # the fit (§4); B' its image of ndc
    return VirtualCamera(window @ to_virtual_clip, shift, near, float(b_depth.max()) + shift, d_r,
                         ndc * window.diagonal()[:3] + window[:3, 3])


def nearest_visible_depth(view: View, light: Light, body: IntersectionBody,
                          options: WarpOptions | None = None) -> float:
    """d_R, the nearest eye depth at which a receiver can be seen (§6's near plane "as far as possible"):
    ``options.visible_depth_range`` when given, else the least eye depth of R ∩ box over the receiver boxes."""
    if options is not None and options.visible_depth_range is not None:
        return max(float(options.visible_depth_range[0]), view.near)
    axis = -view.world_to_camera[2, :3]                     # camera-relative world -> eye depth
    depths = view.eye_depth(body.visible_vertices)
    nearest = body.visible_vertices[int(depths.argmin())] - view.position
    coarse = max(float(depths.min()), view.near)
    boxes = _BoxesByDepth(body.culled.receivers, axis, view.position, coarse)
    best, measured = math.inf, 0
    while (batch := boxes.next(NEAREST_BOX_BATCH, below=best)) is not None:
        lo, hi, bounds = batch
        if bounds[0] <= coarse and np.all((lo <= nearest) & (nearest <= hi), axis=1).any():
            return coarse                                    # R's nearest vertex is in a receiver box
        depths = lowest_in_boxes(body.visible_polytope, lo, hi, axis).tolist()    # (R is camera-relative, as the boxes)
        for bound, depth in zip(bounds, depths):
            if bound >= best:
                break
            if measured >= NEAREST_BOX_CLIPS:                # the nearest box not measured is no nearer than this
                return max(min(best, bound, boxes.unopened), coarse)
            measured += 1
            best = min(best, depth)
    return max(best, coarse) if math.isfinite(best) else coarse


class _BoxesByDepth:
    """A ``Selection``'s receiver boxes, camera-relative, in batches by a lower bound of their eye depth (>= floor)."""

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
        """Add the boxes of clusters [opened, stop) to the pool, in order (none: the pool, already in order, stays)."""
        ids = self.clusters[self.opened:stop]
        more = self.index.c_box_bounds[:, ids][:, self.picked[ids]]                 # (6, boxes): lo, -hi
        pool = np.concatenate([self.pool, more], axis=1)
        lower = np.concatenate([self.pool_lower, np.maximum(self.nearest_corner @ more - self.shift, self.floor)])
        order = np.argsort(lower, kind="stable")
        self.pool, self.pool_lower, self.opened = pool[:, order], lower[order], stop

    def next(self, count: int, below: float):
        """The nearest ``count`` boxes not drawn yet as (lo, hi, bounds); None when no bound left is below ``below``."""
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
    """min k·x over ``region`` ∩ [lo_i, hi_i] for each box i (inf where they do not meet)."""
    return np.minimum(_lowest_on_edges(region.segments, BOX_NORMALS, box_offsets(lo, hi), axis),
                      _lowest_on_edges(box_edges(lo, hi), region.normals, region.offsets, axis))


def _lowest_on_edges(edges: Edges, normals: np.ndarray, offsets: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """min k·x over the edges clipped to the half-spaces, along the last axis (inf: nothing left)."""
    t_lo, t_hi = clip_segments(edges, normals, offsets)
    rise = edges.step @ axis
    t = np.where(t_lo <= t_hi, np.where(rise >= 0, t_lo, t_hi), np.nan)     # NaN: nothing left (t may be infinite)
    return np.fmin.reduce(edges.start @ axis + t * rise, axis=-1, initial=np.inf)


# ---------------------------------------------------------------------------
# The light's cone in PPS (§3): the narrowest cone around B' seen from L'.
# ---------------------------------------------------------------------------

def min_norm_point(points, start=None, max_iter: int = 200) -> np.ndarray:
    """The point of the convex hull of ``points`` (M, d) nearest the origin, by
    Wolfe's algorithm (1976), from the support ``start`` (default: the nearest point)."""
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
    """The weights α (Σ α_i = 1) of the affine hull's point nearest the origin:
    [Q Qᵀ 1; 1ᵀ 0] (α, μ) = (0, 1), by least squares when singular."""
    n = len(q)
    bordered = np.block([[q @ q.T, np.ones((n, 1))], [np.ones((1, n)), np.zeros((1, 1))]])
    rhs = np.eye(n + 1)[n]
    try:
        solution = np.linalg.solve(bordered, rhs)
    except np.linalg.LinAlgError:
        solution = np.linalg.lstsq(bordered, rhs, rcond=None)[0]
    return solution[:n]


def smallest_cone(directions) -> tuple[np.ndarray, float]:
    """Axis k and margin min_i k·d_i of the narrowest cone around the unit ``directions`` (minimax duality:
    Wolfe's nearest point of their hull to the origin)."""
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
    """The light's frustum in PPS: ``matrix`` (PPS -> light clip before the fit; None when no frustum narrower
    than allowed holds B'), L' ``light`` (unit, homogeneous), ``kind``, ``cone_half_angle``, ``single_frustum``."""

    matrix: np.ndarray | None
    light: np.ndarray
    kind: str
    cone_half_angle: float
    single_frustum: bool = True


def pps_light_matrix(light_h, points, max_half_angle: float = math.inf) -> PPSLight:
    """The light frustum from the homogeneous PPS light ``light_h`` over B' (docs/papers.md); no matrix when the
    cone's half-angle exceeds ``max_half_angle``."""
    light = np.asarray(light_h, dtype=np.float64)
    light = light / math.sqrt(light @ light)
    l, w = light[:3], float(light[3])
    directional = abs(w) <= DIRECTIONAL_TOLERANCE * max(math.sqrt(l @ l), 1e-300)
    kind = "directional" if directional else "point" if w > 0 else "inverted"
    b_in_pps = np.asarray(points, dtype=np.float64)
    rays = w * b_in_pps - l                                 # u(p), pointing away from the real light
    lengths = np.sqrt(np.einsum("ij,ij->i", rays, rays))
    if lengths.min() <= 1e-12 * max(float(lengths.max()), 1e-300):
        return PPSLight(None, light, kind, math.pi, False)
    k, margin = smallest_cone(rays / lengths[:, None])
    half = math.acos(min(1.0, max(-1.0, margin)))
    if margin < MIN_CONE_MARGIN or half > max_half_angle:
        return PPSLight(None, light, kind, half, margin >= MIN_CONE_MARGIN)
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
    return PPSLight(frame + np.outer(shear, frame[2]), light, kind, half)
