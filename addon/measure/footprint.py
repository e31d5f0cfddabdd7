"""Texel footprint per pixel (screen pixels per texel) for the report: statistics,
Lloyd's orientation-free perspective factor, and the per-setup wrappers.

The footprint formula itself lives in the warp core, ``addon/warp/aliasing.py``
(one place per formula): with T an orthonormal tangent basis at a surface point,
G = D_view·T (pixels per length), H = D_map·T (texels per length), the footprint
is σ_max(G·H⁻¹), the screen length in pixels of one texel step in the worst
direction (Lloyd's per-point aliasing factor; Stamminger & Drettakis §1.1's
dp = ds·r_s·cosβ/(r_i·cosα) is its 1D form), and |det G|/|det H| its area
version. Footprint > 1 means texels are magnified on screen (blocky edges).
Numpy only.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..warp.aliasing import perspective_aliasing, texel_footprint, texel_footprint_area


def setup_footprints(view, setup, points, normals, map_index=None):
    """(linear, area) footprints of a ShadowSetup at world points: each point is
    measured in the map that serves it (``setup.map_index``); points served by no
    map get NaN; +inf where the surface is edge-on to the map."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    nrm = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    idx = setup.map_index(pts, view) if map_index is None else np.asarray(map_index)
    lin = np.full(len(pts), np.nan)
    area = np.full(len(pts), np.nan)
    for i, m in enumerate(setup.maps):
        sel = idx == i
        if sel.any():
            lin[sel] = texel_footprint(view, m, pts[sel], nrm[sel])
            area[sel] = texel_footprint_area(view, m, pts[sel], nrm[sel])
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
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    idx = setup.map_index(pts, view) if map_index is None else np.asarray(map_index)
    out = np.full(len(pts), np.nan)
    for i, m in enumerate(setup.maps):
        sel = idx == i
        if sel.any():
            out[sel] = perspective_aliasing(view, light, m.matrix, m.size, pts[sel])
    return out
