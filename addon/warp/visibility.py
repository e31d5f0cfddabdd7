"""What the camera sees: the visible region that focuses B (Scherzer §4.4's "visibility algorithm";
Lauritzen et al., *Sample Distribution Shadow Maps*, I3D 2011), conservative, from a depth pre-pass or a
ray cast against the boxes. Why R is cut and not B: docs/papers.md."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .culling import BoxIndex
from .geometry import clip_halfspaces, cross
from .polyhedron import HEXAHEDRON_EDGES, box_corners
from .rays import ray_index, slab_intervals
from .types import EmptyBodyError, Light, SceneBounds, View, WarpOptions


BOX_SAMPLES = (48, 27)
"""The ray grid of :func:`region_from_boxes` (columns, rows) over the image."""
BOX_TILE = 3
"""Samples per tile side of :func:`region_from_boxes`."""
PIXEL_TILE = 16
"""Pixels per tile side of a depth pre-pass (``addon.gpu.visibility``)."""
SURFACE_SAMPLES = 1 << 14
"""At most this many pixels of a depth pre-pass make ``VisibleRegion.surface``."""
DEPTH_ULPS = 16
"""Ulps of 1.0 (2^-24 each, float32 depth) padded on each tile's window depth, then taken to eye depth."""
DEEP_BOX = 0.1
"""A box deeper than this fraction of its least eye depth adds its depths in a square, not all (:func:`_square_depths`)."""
PAIRS = 1 << 14
"""(square, box) pairs :func:`_square_depths` takes at a time (about 64 MB at most for the deepest boxes)."""
KDOP_DIRECTIONS = 8
"""Directions across the light in which the k-DOP bounds the tiles (every 180°/8)."""
KDOP_PAD = 1e-3
"""The k-DOP's planes (angles) move out by this fraction of the region's (angular) extent: float32 GPU rounding."""


@dataclass(frozen=True)
class TileDepths:
    """Per screen tile, the eye-depth interval [near, far] holding every visible point seen through it (near > far:
    nothing seen); ``x_edges``, ``y_edges``: the tiles' NDC edges; ``near``, ``far``: (ny, nx), row 0 at the bottom."""

    x_edges: np.ndarray
    y_edges: np.ndarray
    near: np.ndarray
    far: np.ndarray
    samples: np.ndarray | None = None
    """(ny, nx): how many of the tile's samples (pixels, rays) hit a surface (None: unknown)."""
    edges: np.ndarray | None = None
    """(ny, nx): the length of the shadow edges seen through each tile, in pixels up to a constant (None: unknown;
    ``addon.gpu.visibility.shadow_edges``)."""

    @property
    def seen(self) -> np.ndarray:
        """(ny, nx): the tiles through which something is visible."""
        return self.near <= self.far


@dataclass(frozen=True)
class VisibleRegion:
    """What the camera sees, conservatively: per tile the eye-depth interval of its visible points; its ``source``."""

    tiles: TileDepths
    source: str
    surface: np.ndarray | None = None
    """(N, 2, 3) world points, per sample (pixel, ray) that hit a surface: the nearest and farthest its depth allows."""
    normals: np.ndarray | None = None
    """(N, 3) the unit normal at each ``surface`` sample (the ray cast's faces, the pre-pass's; None: not known)."""
    edge_directions: np.ndarray | None = None
    """(N, 3) the unit direction of the first look's shadow edge at each ``surface`` sample, 0 where none (None)."""

    @property
    def is_empty(self) -> bool:
        return not self.tiles.seen.any()

    @property
    def depth_range(self) -> tuple[float, float]:
        """The nearest and farthest visible eye depth (z_n and z_n + Δz of Scherzer Eq. 1)."""
        seen = self.tiles.seen
        return float(self.tiles.near[seen].min()), float(self.tiles.far[seen].max())

    @property
    def screen(self) -> tuple[float, float, float, float]:
        """(x0, x1, y0, y1): the NDC rectangle of the seen tiles."""
        rows, cols = np.nonzero(self.tiles.seen)
        t = self.tiles
        return (float(t.x_edges[cols.min()]), float(t.x_edges[cols.max() + 1]),
                float(t.y_edges[rows.min()]), float(t.y_edges[rows.max() + 1]))

    def samples(self, view: View) -> tuple[np.ndarray, np.ndarray]:
        """The visible surface as weighted world points: each seen tile's centre at its
        near and far depth, each weighing half its samples (GLPR's guard averages over them)."""
        t = self.tiles
        rows, cols = np.nonzero(t.seen)
        x = (t.x_edges[cols] + t.x_edges[cols + 1]) / 2
        y = (t.y_edges[rows] + t.y_edges[rows + 1]) / 2
        points = unproject(view, np.concatenate([x, x]), np.concatenate([y, y]),
                           np.concatenate([t.near[rows, cols], t.far[rows, cols]]))
        w = np.ones(len(rows)) if t.samples is None else t.samples[rows, cols].astype(np.float64)
        return points, np.concatenate([w, w]) / 2.0

    def edge_weights(self) -> np.ndarray | None:
        """Per point of :meth:`samples`, half its tile's ``TileDepths.edges`` (None: not known)."""
        if self.tiles.edges is None:
            return None
        e = self.tiles.edges[np.nonzero(self.tiles.seen)].astype(np.float64)
        return np.concatenate([e, e]) / 2.0

    def tile_corners(self, view: View) -> np.ndarray:
        """(8 T, 3) world corners of the T seen tiles' depth slabs (their hull holds every visible point)."""
        t = self.tiles
        rows, cols = np.nonzero(t.seen)
        x = np.stack([t.x_edges[cols], t.x_edges[cols + 1]], axis=1)[:, [0, 1, 0, 1]]       # (T, 4)
        y = np.stack([t.y_edges[rows], t.y_edges[rows + 1]], axis=1)[:, [0, 0, 1, 1]]
        depth = np.stack([t.near[rows, cols], t.far[rows, cols]], axis=1)
        return unproject(view, np.tile(x, 2), np.tile(y, 2), np.repeat(depth, 4, axis=1))

    def contains(self, view: View, points, tol: float = 1e-9) -> np.ndarray:
        """Which (N, 3) world points lie in a seen tile's depth slab (depths within ``tol`` relative)."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        h = p @ view.world_to_clip[:, :3].T + view.world_to_clip[:, 3]
        with np.errstate(divide="ignore", invalid="ignore"):
            x, y = h[:, 0] / h[:, 3], h[:, 1] / h[:, 3]
        d = view.eye_depth(p)
        t = self.tiles
        # The tile among the inner edges (a point on the last edge belongs to the last tile).
        col, row = np.searchsorted(t.x_edges[1:-1], x, side="right"), np.searchsorted(t.y_edges[1:-1], y, side="right")
        ok = (h[:, 3] > 0) & (x >= t.x_edges[0]) & (x <= t.x_edges[-1]) & (y >= t.y_edges[0]) & (y <= t.y_edges[-1])
        near, far = t.near[row, col], t.far[row, col]
        return ok & (d >= near - tol * np.abs(near)) & (d <= far + tol * np.abs(far))

    def halfspaces(self, view: View, light: Light) -> tuple[np.ndarray, np.ndarray]:
        """World half-spaces holding every seen tile's depth slab: the eye-depth range,
        the screen rectangle of the seen tiles and a k-DOP of their corners around the light."""
        corners = self.tile_corners(view)
        pad = KDOP_PAD * (float(np.ptp(np.ascontiguousarray(corners.T), axis=1).max()) or 1.0)   # (.T: kdop_halfspaces)
        z_lo, z_hi = self.depth_range
        z_lo, z_hi = max(z_lo - pad, view.near), z_hi + pad       # (a flat region keeps a thickness)
        row = view.world_to_camera[2]                          # eye depth = -(row . [x, 1])
        planes = np.array([row, -row, *screen_sides(view, *self.screen)])
        kn, ko = kdop_halfspaces(corners, view, light, pad)
        return np.concatenate([planes[:, :3], kn]), np.concatenate([-planes[:, 3] + [-z_lo, z_hi, 0, 0, 0, 0], ko])


def screen_sides(view: View, x0, x1, y0, y1) -> np.ndarray:
    """(..., 4, 4): world half-spaces side · [x, 1] <= 0 of the pyramid (an orthographic view's prism) through the NDC
    rectangles [x0, x1] x [y0, y1] (each (..., 1)): x <= x1, y <= y1, x >= x0, y >= y0 (x <= x1: clip_x - x1 w <= 0)."""
    m = view.world_to_clip
    return np.stack([m[0] - x1 * m[3], m[1] - y1 * m[3], x0 * m[3] - m[0], y0 * m[3] - m[1]], axis=-2)


def unproject(view: View, x, y, depth) -> np.ndarray:
    """World points at NDC (x, y) and eye depth ``depth``."""
    x, y, d = (np.asarray(a, dtype=np.float64).ravel() for a in (x, y, depth))
    p = view.projection
    z = -d
    # Row r of the projection: ndc_r · w = p[r] . (X, Y, z, 1) with w = p[3] . (X, Y, z, 1).
    a00, a01 = p[0, 0] - x * p[3, 0], p[0, 1] - x * p[3, 1]
    a10, a11 = p[1, 0] - y * p[3, 0], p[1, 1] - y * p[3, 1]
    b0 = x * (p[3, 2] * z + p[3, 3]) - p[0, 2] * z - p[0, 3]
    b1 = y * (p[3, 2] * z + p[3, 3]) - p[1, 2] * z - p[1, 3]
    det = a00 * a11 - a01 * a10
    cam = np.stack([(b0 * a11 - a01 * b1) / det, (a00 * b1 - b0 * a10) / det, z, np.ones_like(z)], axis=1)
    world = cam @ view.camera_to_world.T
    return world[:, :3] / world[:, 3:]


def eye_depth_from_window(view: View, window_depth, ulps: int = 0) -> np.ndarray:
    """Eye depth on the view axis of window depths (in [0, 1]), each moved by ``ulps`` of 1.0 (2^-24, float32 depth)."""
    p = view.projection
    z = np.asarray(2.0 * np.clip(window_depth + ulps * 2.0 ** -24, 0.0, 1.0) - 1.0, dtype=np.float64)   # NDC depth
    return -(p[2, 3] - z * p[3, 3]) / (z * p[3, 2] - p[2, 2])


def kdop_halfspaces(corners: np.ndarray, view: View, light: Light, pad: float) -> tuple[np.ndarray, np.ndarray]:
    """A k-DOP of ``corners`` around the light (nearest and farthest planes across its depth direction ℓ, the
    tightest planes parallel to ℓ or through the light), moved out by ``pad`` (``KDOP_PAD`` of angles)."""
    base = np.zeros(3) if light.is_directional else np.asarray(light.position, dtype=np.float64)
    rel = corners - base
    mid = np.asarray(light.direction, dtype=np.float64) if light.is_directional else rel.mean(axis=0)
    ell = mid / math.sqrt(mid @ mid) if mid @ mid > 0 else view.direction
    across = _across(ell, view)                                     # (K, 3)
    along, sideways = rel @ ell, rel @ across.T                     # (N,), (N, K)
    # Maxima and minima over the points go along the last axis of (K, N) copies: numpy takes a tenth of the time there
    # that it takes over the short axis of (N, K) (0.5 ms for 4,000 tile corners), and they are exact either way.
    normals = [ell[None], -ell[None]]
    offsets = [[along.max() + pad], [pad - along.min()]]
    if not light.is_directional and along.min() > 0.05 * np.sqrt(np.einsum("ij,ij->i", rel, rel)).max():
        # Planes through the light: angle(rel, ℓ towards m) <= a  <=>  (m cos a - ℓ sin a) . rel <= 0.
        angle = np.ascontiguousarray(np.arctan2(sideways, along[:, None]).T)
        hi, lo = angle.max(axis=1), angle.min(axis=1)
        spread = KDOP_PAD * float((hi - lo).max())
        hi, lo = np.minimum(hi + spread, 0.49 * math.pi), np.maximum(lo - spread, -0.49 * math.pi)
        normals += [np.cos(hi)[:, None] * across - np.sin(hi)[:, None] * ell,
                    np.sin(lo)[:, None] * ell - np.cos(lo)[:, None] * across]
        offsets += [np.zeros(KDOP_DIRECTIONS), np.zeros(KDOP_DIRECTIONS)]
    else:
        normals += [across, -across]
        sideways = np.ascontiguousarray(sideways.T)
        offsets += [sideways.max(axis=1) + pad, pad - sideways.min(axis=1)]
    n = np.concatenate(normals)
    return n, np.concatenate(offsets) + n @ base


def _across(ell: np.ndarray, view: View) -> np.ndarray:
    """(K, 3) unit directions across ℓ, every 180°/K from the maps' +y (``frame.up_across``: V_P, Scherzer Eq. 3), so
    the k-DOP bounds a map's own axes exactly."""
    from .frame import up_across                     # (frame imports body, which imports this module)
    u = up_across(view, ell)
    a = np.arange(KDOP_DIRECTIONS) * (math.pi / KDOP_DIRECTIONS)
    return np.cos(a)[:, None] * u + np.sin(a)[:, None] * cross(ell, u)


# ---------------------------------------------------------------- sources

def tile_reduce(near_samples: np.ndarray, far_samples: np.ndarray, tile: int) -> tuple[np.ndarray, np.ndarray]:
    """Per ``tile`` x ``tile`` block of (H, W) samples (partial at the top, right), least near, greatest far (±inf)."""
    return _blocks(near_samples, tile, np.inf).min(axis=(1, 3)), _blocks(far_samples, tile, -np.inf).max(axis=(1, 3))


def tile_counts(hits: np.ndarray, tile: int) -> np.ndarray:
    """Per ``tile`` x ``tile`` block of an (H, W) boolean image, how many are set."""
    return _blocks(hits, tile, False).sum(axis=(1, 3))


def _blocks(image: np.ndarray, tile: int, fill) -> np.ndarray:
    """An (H, W) image as (rows, tile, columns, tile) blocks, padded with ``fill`` at the top and right."""
    h, w = image.shape
    ny, nx = -(-h // tile), -(-w // tile)
    return np.pad(image, ((0, ny * tile - h), (0, nx * tile - w)), constant_values=fill).reshape(ny, tile, nx, tile)


def tile_edges(samples: int, tile: int) -> np.ndarray:
    """NDC edges of the tiles over ``samples`` sample cells spanning [-1, 1]."""
    cells = np.minimum(np.arange(0, samples + tile, tile), samples)
    return np.unique(cells) * (2.0 / samples) - 1.0


def _region(view: View, near, far, samples: tuple[int, int], tile: int, source: str, counts=None) -> VisibleRegion:
    """A region from tile intervals over ``samples`` = (columns, rows) cells, clamped to the clip range."""
    seen = near <= far
    near, far = (np.where(seen, np.clip(a, view.near, view.far), fill) for a, fill in ((near, np.inf), (far, -np.inf)))
    return VisibleRegion(TileDepths(*(tile_edges(n, tile) for n in samples), near, far, counts), source)


def region_from_window_depth(view: View, window_depth: np.ndarray, tile: int = PIXEL_TILE,
                             source: str = "depth pre-pass") -> VisibleRegion:
    """A region from an (H, W) camera depth buffer (1: nothing drawn), in numpy (``addon.gpu.visibility``'s model)."""
    d = np.asarray(window_depth)
    drawn = d < 1.0
    near, far = tile_reduce(d, np.where(drawn, d, -np.inf), tile)
    return region_from_window_tiles(view, near, far, tile_counts(drawn, tile), d.shape[::-1], tile, source)


def region_from_window_tiles(view: View, near, far, counts, size: tuple[int, int], tile: int = PIXEL_TILE,
                             source: str = "depth pre-pass") -> VisibleRegion:
    """A region from each tile's least and greatest window depth and drawn pixel count
    of a (W, H) depth buffer; each padded by ``DEPTH_ULPS`` before conversion to eye depth."""
    seen = np.asarray(counts) > 0
    with np.errstate(invalid="ignore", divide="ignore"):
        near_eye = eye_depth_from_window(view, np.asarray(near, np.float64), -DEPTH_ULPS)
        far_eye = eye_depth_from_window(view, np.asarray(far, np.float64), DEPTH_ULPS)
    return _region(view, np.where(seen, near_eye, np.inf), np.where(seen, far_eye, -np.inf), size, tile, source,
                   np.where(seen, counts, 0).astype(np.int64))


def surface_from_window_depth(view: View, window_depth: np.ndarray, per_pixel=None) -> tuple[np.ndarray, np.ndarray]:
    """``VisibleRegion.surface`` of an (H, W) depth buffer: every k-th pixel each way (SURFACE_SAMPLES) ± DEPTH_ULPS;
    and the (H, W, ...) ``per_pixel`` at those pixels (None without)."""
    h, w = window_depth.shape
    k = max(1, math.ceil(math.sqrt(h * w / SURFACE_SAMPLES)))
    d = window_depth[k // 2::k, k // 2::k]
    rows, cols = np.nonzero(d < 1.0)
    x, y = (cols * k + k // 2 + 0.5) * (2.0 / w) - 1, (rows * k + k // 2 + 0.5) * (2.0 / h) - 1
    ends = [np.clip(eye_depth_from_window(view, d[rows, cols], s * DEPTH_ULPS), view.near, view.far) for s in (-1, 1)]
    return np.stack([unproject(view, x, y, e) for e in ends], axis=1), \
        None if per_pixel is None else per_pixel[k // 2::k, k // 2::k][rows, cols]


def sample_ndc(n: int) -> np.ndarray:
    """NDC of the centres of ``n`` cells over [-1, 1] and of its ends, which bound the outermost cells' outer halves."""
    return np.concatenate([[-1.0], (np.arange(n) + 0.5) / n * 2 - 1, [1.0]])


def sample_rays(view: View, samples: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Near-plane origins, unit directions and lengths to the far plane of rays through the (rows + 2, columns + 2)
    points of ``sample_ndc`` over the image (a ring on its border around the cells' centres), row 0 at the bottom."""
    gx, gy = np.meshgrid(*(sample_ndc(n) for n in samples))
    near, far = (unproject(view, gx, gy, np.full(gx.size, depth)) for depth in (view.near, view.far))
    length = np.sqrt(np.einsum("ij,ij->i", far - near, far - near))
    return near, (far - near) / length[:, None], length


def region_from_boxes(view: View, scene: SceneBounds, samples: tuple[int, int] = BOX_SAMPLES,
                      tile: int = BOX_TILE) -> VisibleRegion:
    """The visible region of a box scene without a GPU: rays through a ``samples`` grid's cells and the image's border,
    between each four the depths of every box that may show there (docs/papers.md); the last per scene and grid is kept."""
    key = (view.camera_to_world.tobytes(), view.projection.tobytes(), view.near, view.far, samples, tile)
    last = scene.cached(("visible region", samples, tile), dict)
    if last.get("key") != key:
        last.update(key=key, region=_region_from_boxes(view, scene, samples, tile))
    return last["region"]


def _region_from_boxes(view: View, scene: SceneBounds, samples: tuple[int, int], tile: int) -> VisibleRegion:
    nx, ny = samples
    index = BoxIndex.of(scene, "receivers")
    selection = index.select(*clip_halfspaces(view.world_to_clip))
    origins, dirs, length = sample_rays(view, samples)
    t, box = ray_index(origins, dirs, length, index, selection, grid_may_meet(view, index, samples))
    hits = origins + np.where(np.isfinite(t), t, 0.0)[:, None] * dirs
    face, normals = _faces(scene.receivers, hits, box)
    if not scene.solid:              # a box's face hides nothing behind it: every square as at a silhouette, no surface
        face = np.full_like(face, -1)
    # What the square between each four neighbouring rays shows; each cell, the squares within a ray spacing of its own
    # four (padding, as the warps were tuned on).
    near_q, far_q = _square_depths(view, scene.receivers, selection.mask, face.reshape(ny + 2, nx + 2), origins, hits,
                                   samples)
    near, far = tile_reduce(_neighbours(np.pad(near_q, 1, constant_values=np.inf), np.minimum, 4),
                            _neighbours(np.pad(far_q, 1, constant_values=-np.inf), np.maximum, 4), tile)
    cells = box.reshape(ny + 2, nx + 2)[1:-1, 1:-1]                # the cells' rays (the border's: their neighbours)
    hit = np.flatnonzero(np.pad(cells >= 0, 1))                    # the surface: the cells' rays, not the border's
    region = _region(view, near, far, samples, tile, "scene boxes", tile_counts(cells >= 0, tile))
    return replace(region, surface=hits[hit][:, None].repeat(2, axis=1), normals=normals[hit]) if scene.solid else region


def grid_may_meet(view: View, index: BoxIndex, samples) -> np.ndarray:
    """(rays, clusters): whether each ray of ``sample_rays``' grid lies within a cell of the image of the cluster's
    bounds grown by the rays' rounding (NaN: yes), as every ray that meets them does (``rays.ray_index``)."""
    grow = 1e-9 * (view.far + float(np.abs(view.corners()).max()))     # (of V's coordinates: no box far off counts)
    (x0, x1), (y0, y1) = _ndc_rectangles(view, np.stack([index.c_bounds[:3].T - grow, grow - index.c_bounds[3:].T], 1))
    x, y = (g.reshape(-1, 1) for g in np.meshgrid(*(sample_ndc(n) for n in samples)))
    cx, cy = 2.0 / samples[0], 2.0 / samples[1]
    return ~((x < x0 - cx) | (x > x1 + cx) | (y < y0 - cy) | (y > y1 + cy))


def _faces(boxes, hits, box) -> tuple[np.ndarray, np.ndarray]:
    """Per ray sample, 6 box + the face it hit (its box's bounding plane nearest the hit, in ``BOX_NORMALS`` order;
    -1: none) and that face's outward normal."""
    b = boxes[np.maximum(box, 0)]
    face = np.abs(np.concatenate([hits - b[:, 0], hits - b[:, 1]], axis=1)).argmin(axis=1)
    return np.where(box >= 0, 6 * box + face, -1), np.eye(3)[face % 3] * (2.0 * (face // 3) - 1.0)[:, None]


def _box_depths_in_squares(view: View, boxes, xs, ys, col, row) -> tuple[np.ndarray, np.ndarray]:
    """The least and greatest eye depth over box_i ∩ the pyramid of the NDC square [xs[col_i], xs[col_i + 1]] x
    [ys[row_i], ys[row_i + 1]] (inf, -inf: none), over its vertices: the box's corners inside, its edges' crossings of
    the sides, the corner rays' crossings of it."""
    sides = screen_sides(view, xs[col, None], xs[col + 1, None], ys[row, None], ys[row + 1, None])      # (S, 4, 4)
    corners = box_corners(boxes[:, 0], boxes[:, 1])                                              # (S, 8, 3)
    value = np.einsum("sci,sji->scj", corners, sides[:, :, :3]) + sides[:, None, :, 3]           # (S, 8, 4)
    depth = view.eye_depth(corners).reshape(-1, 8)
    tol = 1e-9 * np.abs(value).max(axis=(1, 2))
    which, corner = np.nonzero((value <= tol[:, None, None]).all(axis=2))
    pairs, depths = [which], [depth[which, corner]]
    # Box edges crossing a side, at t = v_a / (v_a - v_b) from corner a to b (values and depth are affine along it);
    # none of an edge whose ends are beyond one side by 2 tol (its points too, by far more than rounding).
    ea, eb = HEXAHEDRON_EDGES.T
    beyond = value > 2 * tol[:, None, None]
    which, edge = np.nonzero(~(beyond[:, ea] & beyond[:, eb]).any(axis=2))
    va, vb = value[which, ea[edge]], value[which, eb[edge]]                                  # (K, 4)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = va / (va - vb)
    k, side = np.nonzero((t >= 0) & (t <= 1))                           # (an edge in a side's plane: NaN, dropped)
    which, edge, t, a, b = which[k], edge[k], t[k, side], va[k], vb[k]
    inside = (a + t[:, None] * (b - a) <= tol[which, None]).all(axis=1)
    da, db = depth[which, ea[edge]], depth[which, eb[edge]]
    pairs.append(which[inside])
    depths.append((da + t * (db - da))[inside])
    # The pyramid's corner rays through the box from the eye (whole lines for an orthographic view's prism): at
    # a >= first from their near plane's point (1 at the far plane), depth affine along them; each ray once.
    gx, gy = np.meshgrid(xs, ys)
    start = unproject(view, gx, gy, np.full(gx.size, view.near))
    ray = unproject(view, gx, gy, np.full(gx.size, view.far)) - start
    ray_of = ((row[:, None] + [0, 0, 1, 1]) * len(xs) + col[:, None] + [0, 1, 0, 1]).ravel()
    start, ray = start[ray_of], ray[ray_of]
    bb = np.repeat(boxes, 4, axis=0)
    with np.errstate(divide="ignore"):
        enter, leave = slab_intervals(start, 1.0 / ray, bb[:, 0], bb[:, 1])
    first = -np.inf if view.orthographic else -view.near / (view.far - view.near)
    met = (enter <= leave) & (leave >= first)
    for at, k in ((enter, met & (enter >= first)), (leave, met)):      # (from inside the box: no surface at entry)
        pairs.append(np.flatnonzero(k) // 4)
        depths.append(view.near + at[k] * (view.far - view.near))
    pairs, depths = np.concatenate(pairs), np.concatenate(depths)
    # Short of the near plane nothing is seen (the region clamps there: a box it cuts shows its surface up to it),
    # and of a box holding the four rays' starts on it, only the inner walls.
    holds = ((enter < 0) & (leave >= 0)).reshape(-1, 4).all(axis=1)
    k = ~(holds[pairs] & (depths < view.near))
    least, most = np.full(len(boxes), np.inf), np.full(len(boxes), -np.inf)
    np.minimum.at(least, pairs[k], depths[k])
    np.maximum.at(most, pairs[k], depths[k])
    unseen = (least > view.far) | (most < view.near)                     # wholly beyond the far or short of the near plane
    return np.where(unseen, np.inf, least), np.where(unseen, -np.inf, most)


def _box_depths(view: View, boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each (M, 2, 3) box's least and greatest eye depth (over its corners)."""
    row = -view.world_to_camera[2]                          # eye depth = row . [x, 1]
    pos, neg = np.maximum(row[:3], 0.0), np.minimum(row[:3], 0.0)
    return boxes[:, 0] @ pos + boxes[:, 1] @ neg + row[3], boxes[:, 1] @ pos + boxes[:, 0] @ neg + row[3]


def _square_depths(view: View, boxes, selected, face, origins, hits, samples) -> tuple[np.ndarray, np.ndarray]:
    """Per square between four neighbouring rays ((rows + 1, columns + 1)), the eye-depth interval [near, far] of every
    point seen through it (near > far: none): one face's corners, the boxes slipping in front of it or, at a silhouette,
    every box meeting the square's pyramid (``DEEP_BOX``); why these bound it: docs/papers.md, ``visibility.py``."""
    xs, ys = (sample_ndc(n) for n in samples)
    one_face = (_neighbours(face, np.minimum) == _neighbours(face, np.maximum)) & (face[1:, 1:] >= 0)
    depth = view.eye_depth(hits).reshape(face.shape)
    near = np.where(one_face, _neighbours(depth, np.minimum), np.inf)
    far = np.where(one_face, _neighbours(depth, np.maximum), -np.inf)
    ends = np.stack([origins, hits]).reshape(2, *face.shape, 3)
    front_lo = np.where(one_face[..., None], _neighbours(ends.min(axis=0), np.minimum), -np.inf).reshape(-1, 3)
    front_hi = np.where(one_face[..., None], _neighbours(ends.max(axis=0), np.maximum), np.inf).reshape(-1, 3)
    ids = np.flatnonzero(selected)
    ranges = []                                   # each box's image as a rectangle of squares
    for e, n, (lo, hi) in zip((xs, ys), samples, _ndc_rectangles(view, boxes[ids])):
        ranges += [np.maximum(np.searchsorted(e, lo, "right") - 1, 0), np.minimum(np.searchsorted(e, hi) - 1, n)]
    count = np.cumsum(np.maximum(ranges[1] - ranges[0] + 1, 0) * np.maximum(ranges[3] - ranges[2] + 1, 0))
    face_far, nearest, columns = np.where(one_face, far, np.inf).ravel(), _box_depths(view, boxes)[0], samples[0] + 1
    for part in np.split(np.arange(len(ids)), np.searchsorted(count, np.arange(PAIRS, count[-1:].sum(), PAIRS))):
        which, q = _rect_cells(*(r[part] for r in ranges), columns)         # (PAIRS at a time: bounded memory)
        # Beside a face: a box nearer than its farthest corner, meeting the rays' hull, not the face's own box.
        keep = nearest[ids[part][which]] < face_far[q]
        which, q = ids[part][which[keep]], q[keep]
        keep = (boxes[which, 0] <= front_hi[q]).all(axis=1) & (boxes[which, 1] >= front_lo[q]).all(axis=1) & \
            ~(one_face.ravel()[q] & (which == face[1:, 1:].ravel()[q] // 6))
        b, q = boxes[which[keep]], q[keep]
        least, most = _box_depths(view, b)
        deep = most - least > DEEP_BOX * np.maximum(least, view.near)
        least[deep], most[deep] = _box_depths_in_squares(view, b[deep], xs, ys, q[deep] % columns, q[deep] // columns)
        np.minimum.at(near.reshape(-1), q, least)
        np.maximum.at(far.reshape(-1), q, np.where(one_face.ravel()[q], -np.inf, most))
    return near, far


def _ndc_rectangles(view: View, boxes) -> list:
    """[(x0, x1), (y0, y1)]: each (M, 2, 3) box's NDC rectangle, of its part beyond the near plane (empty: x0 > x1)."""
    corners = box_corners(boxes[:, 0], boxes[:, 1]).reshape(-1, 3)
    m = view.world_to_clip                                     # clip x, y, w (row by row: numpy's small matmul is slow)
    h = np.stack([corners @ m[r, :3] + m[r, 3] for r in (0, 1, 3)], axis=1).reshape(-1, 8, 3)
    s = view.eye_depth(corners).reshape(-1, 8) - view.near
    keep = s >= 0
    cut = np.flatnonzero(~keep.all(axis=1))      # reaching before the near plane: its edges' crossings of it too
    ea, eb = HEXAHEDRON_EDGES.T
    sa, sb, ha, hb = s[cut][:, ea], s[cut][:, eb], h[cut][:, ea], h[cut][:, eb]
    with np.errstate(divide="ignore", invalid="ignore"):
        cross = ha + (sa / (sa - sb))[..., None] * (hb - ha)
    p, k = np.concatenate([h[cut], cross], axis=1), np.concatenate([keep[cut], (sa < 0) != (sb < 0)], axis=1)
    out = []
    for axis in (0, 1):
        v = h[..., axis] / np.where(keep, h[..., 2], 1.0)
        lo, hi = np.where(keep, v, np.inf).min(axis=1), np.where(keep, v, -np.inf).max(axis=1)
        v = p[..., axis] / np.where(k, p[..., 2], 1.0)
        lo[cut], hi[cut] = np.where(k, v, np.inf).min(axis=1), np.where(k, v, -np.inf).max(axis=1)
        out.append((lo, hi))
    return out


def _neighbours(a: np.ndarray, pick, size: int = 2) -> np.ndarray:
    """``pick`` (``np.minimum``, ``np.maximum``) over each ``size`` x ``size`` block of (H, W, ...) ``a``'s entries."""
    return pick.reduce(np.lib.stride_tricks.sliding_window_view(a, (size, size), axis=(0, 1)), axis=(-2, -1))


def _rect_cells(i0, i1, j0, j1, columns: int) -> tuple[np.ndarray, np.ndarray]:
    """Every (rectangle, cell) pair of the rectangles [i0, i1] x [j0, j1] of cells of a grid ``columns`` wide
    (none where i1 < i0 or j1 < j0): the rectangles' and the cells' flat indices."""
    wide, tall = np.maximum(i1 - i0 + 1, 0), np.maximum(j1 - j0 + 1, 0)
    count = wide * tall
    which = np.repeat(np.arange(len(count)), count)
    k = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    return which, (j0[which] + k // wide[which]) * columns + i0[which] + k % wide[which]


def focused_body(view: View, light: Light, scene: SceneBounds, options: WarpOptions | None = None,
                 visible: VisibleRegion | None = None):
    """B as ``options.focus`` asks (visible region or whole view, Scherzer §4.1); EmptyBodyError if nothing is seen."""
    from .body import intersection_body
    options = options or WarpOptions()
    if options.focus == "view":
        return intersection_body(view, light, scene)
    if scene.is_empty:
        raise EmptyBodyError("the scene has no shadow casters or receivers")
    if visible is None:
        visible = region_from_boxes(view, scene)
    if visible.is_empty:
        raise EmptyBodyError(f"the camera sees no shadow receiver ({visible.source})")
    return intersection_body(view, light, scene, visible)
