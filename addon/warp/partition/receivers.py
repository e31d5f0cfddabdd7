"""The receivers' footprint, where Lloyd's m is blind (edge-on receivers: PSM §1.1's cos α; docs/papers.md)."""
from __future__ import annotations

import numpy as np

from ..aliasing import raster_jacobian
from ..fit import divided, fit_to_unit_cube
from ..geometry import transform_h
from ..polyhedron import convex_polygon_on_plane
from ..types import Light, SceneBounds, ShadowSetup, View, WarpError
from ..visibility import VisibleRegion, region_from_boxes

TAIL = (93.0, 95.0, 97.0)
"""Percentiles about the judge's p95: for n ≈ 1,000 receivers ±2 % is about ±3 binomial σ, sqrt(0.95·0.05/n)."""
SAMPLES = 2048
"""At most this many of a region's receivers (every k-th) score its splits: the engine's pre-pass gives up to 16,384."""
LOSS, EDGES = 2.0, 20
"""How much more an aligned map's footprint counts (``filter_losses``), and the edge samples that weigh in full."""
RAYS = (64, 36)
"""The receivers' rays (columns, rows) where the region is the scene boxes' 48x27 ray cast (docs/papers.md)."""


def receivers(view: View, light: Light, region: VisibleRegion | None, near: float, far: float,
              scene: SceneBounds | None = None) -> tuple | None:
    """(p, n, tangent bases T (N, 3, 2), G = D_view·T, (M, 3, 3) each sample, its ``edge_directions`` and normal)
    of the ``region``'s ``surface`` samples and ``normals`` at eye depths [near, far) that the light reaches (a spot's
    cone); None if none. The boxes' ray cast is cast again through ``RAYS`` (48x27 leaves a p95 at walls to chance)."""
    if region is None or region.normals is None:
        return None
    cast = scene is not None and region.source == "scene boxes"
    region = region_from_boxes(view, scene, RAYS) if cast else region
    step = 1 if cast else max(1, -(-len(region.normals) // SAMPLES))
    p, n, e = region.surface[::step, 0], region.normals[::step], edge_samples(region)
    k = (view.eye_depth(p) >= near) & (view.eye_depth(p) < far)
    if light.type == "SPOT":
        k &= light.rays_to(p) @ light.direction >= np.cos(light.spot_angle / 2)
    p, n = p[k], n[k]
    t1 = np.cross(n, np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]]))
    tangent = np.stack([t1, np.cross(n, t1)], axis=2) / np.linalg.norm(t1, axis=1)[:, None, None]
    return (p, n, tangent, raster_jacobian(view.world_to_clip, view.resolution, p) @ tangent, e) if len(p) else None


def edge_samples(region: VisibleRegion | None) -> np.ndarray:
    """(M, 3, 3): each of the ``region``'s shadow-edge samples' point, ``edge_directions`` and normal (none unknown)."""
    e = None if region is None or region.normals is None else region.edge_directions
    return np.zeros((0, 3, 3)) if e is None else np.stack([region.surface[:, 0], e, region.normals], 1)[np.any(e != 0, 1)]


def footprints(setups: list, seen: tuple) -> list[np.ndarray]:
    """Screen pixels per texel σ_max(G·H⁻¹) of each of ``setups`` at the ``receivers`` ``seen``, H = D_map·T of the map
    serving each (inf edge-on, NaN unserved): the judge's ``addon.measure.footprint`` (PSM §1.1), in one batch."""
    p, _, tangent, g, _ = seen
    # H = D_M·T, and j = H·Rᵀ·Gᵀ = R·(G·adj H)ᵀ, R the quarter turn: G·H⁻¹·det H's singular values, its determinant
    trg = tangent @ np.array([[0.0, -1.0], [1.0, 0.0]]) @ np.swapaxes(g, 1, 2)                          # T·Rᵀ·Gᵀ
    h, j = np.split(jacobians([m for s in setups for m in s.maps], p, np.concatenate([tangent, trg], 2)), 2, axis=3)
    f2, det_j, det_h = entries(j * j, np.add), det2(j), np.abs(det2(h))
    with np.errstate(divide="ignore", invalid="ignore"):
        sigma = np.sqrt((f2 + np.sqrt(np.maximum(f2 * f2 - 4.0 * det_j * det_j, 0.0))) / 2.0) / det_h
    sigma = np.where(det_h > 1e-14 * entries(np.abs(h), np.maximum) ** 2, sigma, np.inf)
    first = np.cumsum([0] + [len(s.maps) for s in setups])[:-1, None]
    served = np.array([s.map_index(p, None, 1e-6) if len(s.maps) > 1 else np.zeros(len(p), int) for s in setups])
    return list(np.where(served >= 0, sigma[first + served, np.arange(len(p))], np.nan))


def jacobians(maps: list, points: np.ndarray, vectors: np.ndarray | None = None) -> np.ndarray:
    """(M, N, 2, k) D_M·``vectors`` (N, 3, k; None: D_M) of each of ``maps`` at the ``points``: one ``raster_jacobian``
    per group with equal z, w rows and x, y rows A·(x, y rows) + t ⊗ (w row) of its first's (turns), A·D_M for each."""
    matrix = np.array([m.matrix for m in maps], dtype=np.float64)
    base, group = np.unique(matrix[:, 2:].reshape(-1, 8), axis=0, return_index=True, return_inverse=True)[1:]
    # x, y rows A·(x, y) + t·w over the same w: d(x/w, y/w) = A·d(x/w, y/w) + t·d(w/w), A times the first's D_M
    c = matrix[:, :2] @ np.linalg.pinv(xyw := matrix[base][:, [0, 1, 3]])[group]             # [A | t], (M, 2, 3)
    alike = np.abs(c @ xyw[group] - matrix[:, :2]).max(axis=(1, 2)) <= 1e-12 * np.abs(matrix[:, :2]).max(axis=(1, 2))
    bases, group = np.unique(np.where(alike, base[group], np.arange(len(maps))), return_inverse=True)
    d = raster_jacobian(matrix[bases], [(2, 2)] * len(bases), points)
    d = d if vectors is None else d @ vectors                                                 # (G, N, 2, k)
    a = np.where(np.all(matrix == matrix[bases[group]], axis=(1, 2))[:, None, None], np.eye(2), c[..., :2])
    a *= np.array([m.size for m in maps], dtype=np.float64)[:, :, None] / 2.0                 # diag(w, h)/2·A
    images = a @ np.moveaxis(d, 2, 1).reshape(len(bases), 2, d.shape[1] * d.shape[3])[group]   # (M, 2, N·k)
    return np.moveaxis(images.reshape(len(maps), 2, *d.shape[1::2]), 1, 2)


def filter_losses(setups: list, seen: tuple) -> np.ndarray:
    """Per setup, 1 + ``LOSS``·the mean over the ``receivers`` ``seen``'s n shadow edges e of min(1, (20° - a)/12°)⁺, a
    the angle of D_M·e to a texel axis of its one map (several: 1), times min(1, n/``EDGES``): a grid along an edge
    holds nothing of the edge's place in a texel, and PCF 2 gains 3-7 % there, 16-33 % at 20-45° (docs/papers.md, the
    cascade's edges); below ``EDGES`` samples the share is shrunk toward the no-edge pick's 0, as if the missing ones
    were not aligned, so that a split's weight grows with its evidence rather than jumping at a threshold. Times the
    texel's mean width across those edges on their surfaces, |D_M·e| / |D_M·e × D_M·(n × e)|, over the least of the
    single maps' (shrunk alike): the wrong pixels follow Σ |Jᵀn|·E|δ(a)| (docs/papers.md, "The far split's edges")."""
    if not len(seen[4]) or not setups:
        return np.ones(len(setups))
    e, n = seen[4][:, 1], seen[4][:, 2]
    v, w = np.moveaxis(jacobians([s.maps[0] for s in setups], seen[4][:, 0], np.stack([e, np.cross(n, e)], 2)), 3, 0)
    aligned = np.clip((20.0 - np.degrees(np.arctan2(np.abs(v).min(axis=2), np.abs(v).max(axis=2)))) / 12.0, 0.0, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        width = np.linalg.norm(v, axis=2) / np.abs(v[..., 0] * w[..., 1] - v[..., 1] * w[..., 0])
    single, evidence = np.array([len(s.maps) == 1 for s in setups]), min(1.0, len(seen[4]) / EDGES)
    width = np.ma.masked_invalid(width).mean(axis=1).filled(np.nan)  # over the edges in front of it (none: no loss)
    wider = np.nan_to_num(width / np.nanmin(width[single], initial=np.inf) - 1.0) * evidence * single
    return (1.0 + LOSS * np.ma.masked_invalid(aligned).mean(axis=1).filled(0.0) * evidence * single) * (1.0 + wider)


def grazing(setup: ShadowSetup, seen: tuple, light: Light, top: float = 90.0) -> tuple:
    """(points, m = n × ℓ) of the receivers ``seen`` whose footprint in ``setup``'s single map is above its ``top``
    percentile: m, kept by the projection along ℓ, is the length of each one's strip (docs/papers.md)."""
    f = footprints([setup], seen)[0]
    k = np.isfinite(f)
    k &= f >= (np.percentile(f[k], top) if k.any() else np.inf)
    return seen[0][k], np.cross(seen[1][k], light.rays_to(seen[0][k]))


def det2(a: np.ndarray) -> np.ndarray:
    """The determinants of a stack of 2x2 matrices (np.linalg.det: LAPACK per 2x2)."""
    return a[..., 0, 0] * a[..., 1, 1] - a[..., 0, 1] * a[..., 1, 0]


def entries(a: np.ndarray, op) -> np.ndarray:
    """``op`` over a stack of 2x2 matrices' entries in ``a.sum(axis=(-2, -1))``'s order (7x faster than it)."""
    return op(op(op(a[..., 0, 0], a[..., 0, 1]), a[..., 1, 0]), a[..., 1, 1])


def footprint_p95(footprints: list, band=(95.0,)) -> float:
    """The judge's p95 of the finite values of ``footprints`` (edge-on left out; none: inf), or the geometric mean of
    the percentiles of a ``band`` about it (``TAIL``: a p95 at a cliff of the distribution does not decide alone)."""
    v = np.sort(np.concatenate(footprints))          # edge-on (inf), unserved (NaN) last; np.percentile is 3x slower
    k = int(np.isfinite(v).sum())
    return float(np.exp(np.log(np.interp(np.multiply(band, (k - 1) / 100), np.arange(k), v[:k])).mean())) if k else np.inf


def footprint_p95s(fixed: list, choices: list) -> np.ndarray:
    """``footprint_p95(fixed + [c])`` of each of ``choices`` (not empty) at once, inf for a c with no finite value (it
    serves none of its receivers: never picked over one that does): the value at rank r = ⌊0.95·(n - 1)⌋ of the n
    finite ones is their (n - 1 - r)-th largest, found among as many of each part's largest (one partition)."""
    f, c = np.concatenate([np.zeros(0), *fixed]), np.full((len(choices), max(map(len, choices))), -np.inf)
    c[np.arange(c.shape[1]) < np.array([len(v) for v in choices])[:, None]] = np.concatenate(choices)
    f, n = -np.sort(-f[np.isfinite(f)]), np.isfinite(f).sum() + np.isfinite(c).sum(axis=1)
    x = 95.0 * ((n - 1) / 100)
    r = np.floor(x).astype(int)
    q = int((n - 1 - r).max()) + 1
    c = np.c_[np.where(np.isfinite(c), c, -np.inf), np.full((len(c), max(q - c.shape[1], 0)), -np.inf)]
    tops = np.c_[np.broadcast_to(f[:q], (len(c), len(f[:q]))), np.partition(c, c.shape[1] - q, axis=1)[:, -q:]]
    tops = -np.sort(-tops, axis=1)[np.arange(len(choices))[:, None], np.maximum((n - 1 - r)[:, None] - [0, 1], 0)]
    with np.errstate(divide="ignore", invalid="ignore"):               # (v_(r+1) - v_r)·(x - r) + v_r: np.interp's
        return np.where(np.isfinite(c).any(1), np.exp(np.log((tops[:, 1] - tops[:, 0]) * (x - r) + tops[:, 0])), np.inf)


def turned(matrix: np.ndarray, points: np.ndarray, along: tuple | None = None) -> list[np.ndarray]:
    """``matrix`` turned about its depth axis (about ℓ for a sun) to lay each edge of the points' image hull, or the
    mean image of ``along``'s directions, along a texel axis, refitted to the points (Freeman & Shapira 1975)."""
    j = raster_jacobian(matrix, (2, 2), points.mean(axis=0)[None])[0]
    w, v = np.linalg.eigh(j @ j.T)
    metric = (v / np.sqrt(w)) @ v.T                                   # (J·Jᵀ)^(-1/2): NDC to lengths across ℓ
    try:
        xy = divided(transform_h(matrix, points))[:, :2] @ metric.T
    except WarpError:                                                 # an inverted map (w < 0 on B): left as it is
        return []
    if along is not None:
        d = (raster_jacobian(matrix, (2, 2), along[0]) @ along[1][..., None])[..., 0] @ metric.T
        angles = [np.angle(np.nansum(np.exp(4j * np.arctan2(d[:, 1], d[:, 0])))) / 4] if len(d) else []   # mod 90°
    else:
        hull = convex_polygon_on_plane(np.c_[xy, np.zeros(len(xy))], (0.0, 0.0, 1.0), 1e-9 * float(np.ptp(xy)))
        edges = np.zeros((0, 2)) if hull is None else (np.roll(hull, -1, axis=0) - hull)[:, :2]
        angles = np.unique(np.round(np.mod(np.arctan2(edges[:, 1], edges[:, 0]), np.pi / 2), 3))
    c, s = np.cos(angles), np.sin(angles)                              # the turns fitted at once: (K, 4, 4)
    turns = np.stack([np.stack([c, s], -1), np.stack([-s, c], -1)], -2) @ metric @ matrix[:2]
    return list(fit_to_unit_cube(np.concatenate([turns, np.broadcast_to(matrix[2:], (len(c), 2, 4))], 1), points))


def spun(matrix: np.ndarray, points: np.ndarray, turns: np.ndarray) -> list[np.ndarray]:
    """``matrix`` turned about its depth axis by each of ``turns`` (``TURNS``), refitted to the ``points`` in front
    of its near plane and where their segments cross it (a point light on B is a vertex of B, w = 0: its own window)."""
    s = points @ (matrix[2, :3] + matrix[3, :3]) + matrix[2, 3] + matrix[3, 3]          # w·(z_ndc + 1)
    f, b = s > 0, s <= 0
    on = points[f, None] + (points[None, b] - points[f, None]) * (s[f, None] / (s[f, None] - s[None, b]))[..., None]
    try:
        return list(fit_to_unit_cube(turns @ matrix, np.concatenate([points[f], on.reshape(-1, 3)])))
    except WarpError:                                                 # (w <= 0 in front of it: left as it is)
        return []
