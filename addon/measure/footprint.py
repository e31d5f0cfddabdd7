"""Texel footprint per pixel: how many screen pixels one shadow-map texel spans.

For a visible surface point p with unit normal n, both the screen and the shadow
map parameterize the surface near p. With T = [t1 t2] an orthonormal basis of the
tangent plane and, for a 4x4 projective map M onto an R_x x R_y raster,

    D_M(p) = diag(R_x, R_y)/2 · (M[:2, :3] - ndc ⊗ M[3, :3]) / w      (d raster / d world)

(ndc = M p / w, the projective divide's derivative), the local rasters are
G = D_view(p)·T (pixels per unit length along the surface) and H = D_map(p)·T
(texels per unit length). The texel -> pixel Jacobian is G·H⁻¹, and the
**footprint** is its largest singular value: the screen length, in pixels, of
one texel step in the worst direction (Lloyd's per-point aliasing factor m;
Stamminger & Drettakis §1.1 dp = ds·r_s·cosβ/(r_i·cosα) is its 1D form).
Footprint > 1 means texels are magnified on screen (blocky shadow edges).
``area_footprint`` = |det G| / |det H| is the pixels-per-texel area ratio.

Maps with ``depth_row`` (linear z) only change depth, never x/y, so they do not
affect the footprint. Numpy only.

NOTE (one place per formula): ``addon/warp/aliasing.py`` is to get the warp
core's per-point footprint Jacobian; when it lands this module should call it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..warp.geometry import homogeneous


def raster_jacobian(matrix, size, points) -> np.ndarray:
    """d(raster coords)/d(world) (N, 2, 3) of the projective ``matrix`` onto a
    ``size`` = (w, h) raster (raster x = (ndc_x + 1)/2·w), at (N, 3) points."""
    m = np.asarray(matrix, dtype=np.float64)
    h = homogeneous(points) @ m.T
    w = h[:, 3]
    ndc = h[:, :2] / w[:, None]
    d = (m[None, :2, :3] - ndc[:, :, None] * m[None, 3:4, :3]) / w[:, None, None]
    scale = np.array([size[0], size[1]], dtype=np.float64) / 2.0
    return d * scale[None, :, None]


def tangent_basis(normals) -> np.ndarray:
    """(N, 3, 2): two orthonormal tangent vectors per unit normal."""
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    helper = np.where(np.abs(n[:, :1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    t1 = np.cross(n, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(n, t1)
    return np.stack([t1, t2], axis=2)


def footprints(view_matrix, view_size, map_matrix, map_size, points, normals):
    """(linear, area) footprints (N,) of one map at points with normals.

    ``view_matrix`` is the camera's world -> clip (``View.world_to_clip``) and
    ``view_size`` its resolution. Points where the surface is edge-on to the map
    (H singular) get +inf."""
    t = tangent_basis(normals)
    g = raster_jacobian(view_matrix, view_size, points) @ t       # (N, 2, 2) pixels / length
    h = raster_jacobian(map_matrix, map_size, points) @ t         # (N, 2, 2) texels / length
    det_h = np.linalg.det(h)
    det_g = np.linalg.det(g)
    ok = np.abs(det_h) > 1e-300
    lin = np.full(len(t), np.inf)
    area = np.full(len(t), np.inf)
    if ok.any():
        j = g[ok] @ np.linalg.inv(h[ok])                          # d pixel / d texel
        lin[ok] = np.linalg.svd(j, compute_uv=False)[:, 0]
        area[ok] = np.abs(det_g[ok] / det_h[ok])
    return lin, area


def setup_footprints(view, setup, points, normals, map_index=None):
    """Footprints (linear, area) of a ShadowSetup at world points: each point is
    measured in the map that serves it (``setup.map_index``); points served by no
    map get NaN."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    nrm = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    idx = setup.map_index(pts, view) if map_index is None else np.asarray(map_index)
    lin = np.full(len(pts), np.nan)
    area = np.full(len(pts), np.nan)
    for i, m in enumerate(setup.maps):
        sel = idx == i
        if sel.any():
            lin[sel], area[sel] = footprints(view.world_to_clip, view.resolution, m.matrix, m.size, pts[sel], nrm[sel])
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
    """Lloyd's perspective aliasing factor per point, the quantity his N_min bounds.

    Both densities are taken per unit area on the plane through p perpendicular
    to the light ray (so the surface orientation - projection aliasing, which
    no warp can change - drops out): the pixels needed there are K / z(p)²
    (``lloyd.pixel_density_constant``, z the eye depth; K alone for an
    orthographic view), the texels given are |det H⊥| with H⊥ the map's raster
    Jacobian on that plane. The factor is sqrt(needed / given); with the best
    possible warp of N texels its maximum over the frustum is m_min =
    sqrt(N_min / N). NaN for points served by no map."""
    from .lloyd import pixel_density_constant

    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    idx = setup.map_index(pts, view) if map_index is None else np.asarray(map_index)
    rays = light.rays_to(pts)
    basis = tangent_basis(rays)                      # two unit vectors perpendicular to each ray
    k = pixel_density_constant(view)
    need = np.full(len(pts), k) if view.orthographic else k / view.eye_depth(pts) ** 2
    out = np.full(len(pts), np.nan)
    for i, m in enumerate(setup.maps):
        sel = idx == i
        if sel.any():
            given = np.abs(np.linalg.det(raster_jacobian(m.matrix, m.size, pts[sel]) @ basis[sel]))
            with np.errstate(divide="ignore"):
                out[sel] = np.sqrt(need[sel] / given)
    return out
