"""Texel footprint per pixel (screen pixels per texel) for the report: statistics,
Lloyd's orientation-free perspective factor, and the per-setup wrappers.

The footprint formula (:func:`texel_footprint`): with T an orthonormal tangent
basis at a surface point, G = D_view·T (pixels per length), H = D_map·T (texels per length), the footprint
is σ_max(G·H⁻¹), the screen length in pixels of one texel step in the worst
direction (Lloyd's per-point aliasing factor; Stamminger & Drettakis §1.1's
dp = ds·r_s·cosβ/(r_i·cosα) is its 1D form), and |det G|/|det H| its area
version. Footprint > 1 means texels are magnified on screen (blocky edges).
Numpy only.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..warp.aliasing import perspective_aliasing, raster_jacobian


def tangent_basis(normals) -> np.ndarray:
    """(N, 3, 2): two orthonormal tangent vectors per normal."""
    nrm = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    nrm = nrm / np.linalg.norm(nrm, axis=1, keepdims=True)
    helper = np.where(np.abs(nrm[:, :1]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    t1 = np.cross(nrm, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(nrm, t1)
    return np.stack([t1, t2], axis=2)


def _surface_jacobians(view, shadow_map, points, normals):
    t = tangent_basis(normals)
    g = raster_jacobian(view.world_to_clip, view.resolution, points) @ t     # pixels per length
    h = raster_jacobian(shadow_map.matrix, shadow_map.size, points) @ t      # texels per length
    return g, h


def texel_footprint(view, shadow_map, points, normals) -> np.ndarray:
    """Screen pixels per texel, σ_max(G·H⁻¹), at (N, 3) surface ``points`` with ``normals``
    (+inf edge-on to the map, NaN where w <= 0 for the camera or the map)."""
    g, h = _surface_jacobians(view, shadow_map, points, normals)
    out = np.full(len(g), np.nan)
    valid = np.all(np.isfinite(g), axis=(1, 2)) & np.all(np.isfinite(h), axis=(1, 2))
    det_h = np.zeros(len(g))
    det_h[valid] = np.linalg.det(h[valid])
    scale = np.max(np.abs(h), axis=(1, 2), initial=0.0, where=np.isfinite(h))
    singular = valid & (np.abs(det_h) <= 1e-14 * scale ** 2)
    out[singular] = np.inf
    ok = valid & ~singular
    if ok.any():
        hi = h[ok]
        adj = np.stack([np.stack([hi[:, 1, 1], -hi[:, 0, 1]], axis=1),
                        np.stack([-hi[:, 1, 0], hi[:, 0, 0]], axis=1)], axis=1)
        j = g[ok] @ adj / det_h[ok][:, None, None]                            # d pixel / d texel
        out[ok] = np.linalg.svd(j, compute_uv=False)[:, 0]
    return out


def texel_footprint_area(view, shadow_map, points, normals) -> np.ndarray:
    """Screen pixels per texel by area, |det G| / |det H| (+inf edge-on, NaN where w <= 0)."""
    g, h = _surface_jacobians(view, shadow_map, points, normals)
    out = np.full(len(g), np.nan)
    valid = np.all(np.isfinite(g), axis=(1, 2)) & np.all(np.isfinite(h), axis=(1, 2))
    if valid.any():
        with np.errstate(divide="ignore", invalid="ignore"):
            out[valid] = np.abs(np.linalg.det(g[valid])) / np.abs(np.linalg.det(h[valid]))
    return out


def per_serving_map(view, setup, points, measure, *per_point, map_index=None) -> np.ndarray:
    """``measure(shadow_map, points, *per_point)`` of a ShadowSetup at (N, 3) world ``points``, each point measured in
    the map that serves it (``setup.map_index``, or ``map_index``); NaN for points that no map serves."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    idx = setup.map_index(pts, view) if map_index is None else np.asarray(map_index)
    out = np.full(len(pts), np.nan)
    for i, m in enumerate(setup.maps):
        sel = idx == i
        if sel.any():
            out[sel] = measure(m, pts[sel], *(a[sel] for a in per_point))
    return out


def setup_texel_footprint(view, setup, points, normals) -> np.ndarray:
    """:func:`texel_footprint` of a ShadowSetup, each point in the map that serves it (NaN: none)."""
    nrm = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    return per_serving_map(view, setup, points, lambda m, p, n: texel_footprint(view, m, p, n), nrm)


def setup_footprints(view, setup, points, normals, map_index=None):
    """(linear, area) footprints of a ShadowSetup at world points: each point is
    measured in the map that serves it (``setup.map_index``); points served by no
    map get NaN; +inf where the surface is edge-on to the map."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    nrm = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    idx = setup.map_index(pts, view) if map_index is None else np.asarray(map_index)
    lin = per_serving_map(view, setup, pts, lambda m, p, n: texel_footprint(view, m, p, n), nrm, map_index=idx)
    area = per_serving_map(view, setup, pts, lambda m, p, n: texel_footprint_area(view, m, p, n), nrm, map_index=idx)
    return lin, area


@dataclass
class FootprintStats:
    """Summary of per-pixel linear footprints over the measured pixels."""

    max: float
    p95: float
    mean: float
    frac_above_1: float
    count: int

    def to_json(self) -> dict:
        return {"max": self.max, "p95": self.p95, "mean": self.mean, "frac_above_1": self.frac_above_1,
                "count": self.count}


def footprint_stats(values, mask=None) -> FootprintStats:
    """max, 95th percentile, mean and the fraction above 1 of the finite values
    (within ``mask``). Infinite values (edge-on to the map) count as above 1 and
    make the max infinite but are left out of the mean and p95."""
    v = np.asarray(values, dtype=np.float64).ravel()
    if mask is not None:
        v = v[np.asarray(mask, dtype=bool).ravel()]
    v = v[~np.isnan(v)]
    if len(v) == 0:
        return FootprintStats(float("nan"), float("nan"), float("nan"), float("nan"), 0)
    fin = v[np.isfinite(v)]
    return FootprintStats(
        max=float(v.max()),
        p95=float(np.percentile(fin, 95)) if len(fin) else float("inf"),
        mean=float(fin.mean()) if len(fin) else float("inf"),
        frac_above_1=float(np.mean(v > 1.0)),
        count=int(len(v)),
    )


def perspective_footprints(view, light, setup, points, map_index=None) -> np.ndarray:
    """Lloyd's perspective aliasing factor per point, the quantity his N_min bounds
    (``addon.warp.aliasing.perspective_aliasing``: pixels needed K / z(p)² and
    texels given |det H⊥| per unit area across the light ray, so the surface
    orientation drops out), each point measured in the map that serves it.
    With the best possible warp of N texels its maximum over the frustum is
    m_min = sqrt(N_min / N). NaN for points served by no map."""
    return per_serving_map(view, setup, points, lambda m, p: perspective_aliasing(view, light, m.matrix, m.size, p),
                           map_index=map_index)


EDGE_NORMAL_RADIUS = 4
"""The pixels within this radius of an edge pixel (a disc) give its edge's normal (:func:`shadow_edge_normals`)."""


def shadow_edge_normals(truth, valid, radius: int = EDGE_NORMAL_RADIUS) -> np.ndarray:
    """(H, W, 2) unit normals on screen (x right, y up: row 0 at the bottom) of the true shadow edges, pointing into
    the shadow: the gradient of the shadow image over the valid pixels of a disc of ``radius`` pixels about each pixel
    (Σ (s_q − s̄)(q − p), s̄ their mean), or with ``radius`` 1 its 3 x 3 Sobel gradient (an invalid neighbour counted
    as the pixel's own state), which turns with the edge within two pixels (``bench.edge_footprint``'s corners) but
    is exact at 0°, 45° and 90° only: on straight edges elsewhere it errs by 6° (median), against 1.2° at radius 4,
    and where a texel is long on the receiver |Jᵀn| (:func:`across_edge_width`) swings with it: gen2_08_low_sun's
    uniform 2048² read 0.72 px across its straight edges by Sobel, 0.36 at radius 4 and 0.33 from the edges fitted
    in a ground truth 4 x 4 times finer. NaN where the gradient vanishes or the pixel is not valid."""
    t = np.asarray(truth, dtype=np.float64)
    v = np.asarray(valid, dtype=bool)
    h, w = t.shape
    if radius == 1:
        pad_t, pad_v = np.pad(t, 1), np.pad(v, 1)

        def at(dy, dx):
            return np.where(pad_v[1 + dy:1 + dy + h, 1 + dx:1 + dx + w], pad_t[1 + dy:1 + dy + h, 1 + dx:1 + dx + w], t)
        gx = at(-1, 1) + 2 * at(0, 1) + at(1, 1) - at(-1, -1) - 2 * at(0, -1) - at(1, -1)
        gy = at(1, -1) + 2 * at(1, 0) + at(1, 1) - at(-1, -1) - 2 * at(-1, 0) - at(-1, 1)
    else:
        r = int(radius)
        pad_t, pad_v = np.pad(t, r), np.pad(v, r).astype(np.float64)
        count, shadowed, gx, gy, ox, oy = (np.zeros((h, w)) for _ in range(6))
        disc = [(dy, dx) for dy in range(-r, r + 1) for dx in range(-r, r + 1) if dx * dx + dy * dy <= r * r + r]
        for dy, dx in disc:
            vq = pad_v[r + dy:r + dy + h, r + dx:r + dx + w]
            sq = vq * pad_t[r + dy:r + dy + h, r + dx:r + dx + w]
            count += vq
            shadowed += sq
            gx += dx * sq
            gy += dy * sq
            ox += dx * vq
            oy += dy * vq
        mean = shadowed / np.maximum(count, 1.0)
        gx, gy = gx - mean * ox, gy - mean * oy
    length = np.hypot(gx, gy)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.stack([gx, gy], axis=-1) / length[..., None]
    out[~v | (length <= 1e-9)] = np.nan
    return out


def across_edge_width(view, shadow_map, points, normals, edge_normals) -> np.ndarray:
    """Screen pixels that one texel spans across a shadow edge with unit screen normal n at (N, 3) surface
    ``points``: |Jᵀn|, J = G·H⁻¹ the pixels per texel of :func:`texel_footprint`. A map puts each shadow edge on its
    texel grid, so the rendered edge moves across itself by up to about half of this; summed over the pixels of the
    true edges it predicts a map's edge error where σ_max (:func:`texel_footprint`) only bounds it
    (``bench.edge_footprint``). +inf edge-on to the map, NaN where w <= 0."""
    g, h = _surface_jacobians(view, shadow_map, points, normals)
    n = np.asarray(edge_normals, dtype=np.float64).reshape(-1, 2)
    out = np.full(len(g), np.nan)
    ok = np.all(np.isfinite(g), axis=(1, 2)) & np.all(np.isfinite(h), axis=(1, 2)) & np.all(np.isfinite(n), axis=1)
    det_h = np.linalg.det(np.where(ok[:, None, None], h, np.eye(2)))
    scale = np.max(np.abs(np.where(ok[:, None, None], h, 0.0)), axis=(1, 2))
    singular = ok & (np.abs(det_h) <= 1e-14 * scale ** 2)
    out[singular] = np.inf
    ok &= ~singular
    if ok.any():
        j = g[ok] @ np.linalg.inv(h[ok])                                  # d pixel / d texel
        out[ok] = np.linalg.norm(np.einsum("nij,ni->nj", j, n[ok]), axis=1)
    return out


def setup_across_edge_width(view, setup, points, normals, edge_normals, map_index=None) -> np.ndarray:
    """:func:`across_edge_width` of a ShadowSetup, each point in the map that serves it (NaN: none)."""
    nrm = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    en = np.asarray(edge_normals, dtype=np.float64).reshape(-1, 2)
    return per_serving_map(view, setup, points, lambda m, p, n, e: across_edge_width(view, m, p, n, e), nrm, en,
                           map_index=map_index)
