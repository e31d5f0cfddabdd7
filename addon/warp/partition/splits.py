"""z-partitioning of the view (Scherzer §3): z_n = C_0 < ... < C_N = z_f, split i the slab C_i <= eye depth <=
C_(i+1) of V, by PSSM's practical scheme C_i = λ·z_n·(z_f/z_n)^(i/N) + (1 - λ)·(z_n + (z_f - z_n)·i/N) over
[z_n, z_f] tightened to the visible receivers (docs/papers.md, ``addon/warp/partition``)."""
from __future__ import annotations

import dataclasses

import numpy as np

from ..body import IntersectionBody
from ..geometry import frustum_matrix, ortho_matrix
from ..post_perspective import nearest_visible_depth
from ..types import Light, View, WarpOptions
from ..visibility import VisibleRegion


def practical_splits(z_n: float, z_f: float, count: int, lam: float) -> np.ndarray:
    """C_0..C_N (C_0 = z_n, C_N = z_f exactly) for 0 < z_n < z_f: λ ∈ [0, 1], 1 logarithmic, 0 uniform."""
    i_over_n = np.arange(count + 1) / count
    c = lam * (z_n * (z_f / z_n) ** i_over_n) + (1.0 - lam) * (z_n + (z_f - z_n) * i_over_n)
    c[0], c[-1] = z_n, z_f
    return c


def tightened_depth_range(view: View, light: Light, body: IntersectionBody,
                          options: WarpOptions) -> tuple[float, float]:
    """[z_n, z_f] (module docs), within the camera's clip range."""
    z_n, z_f = nearest_visible_depth(view, light, body), float(view.eye_depth(body.visible_vertices).max())
    ranges = [options.visible_depth_range] + ([body.visible.depth_range] if body.visible is not None else [])
    for near, far in (r for r in ranges if r is not None):
        z_n, z_f = max(z_n, float(near)), min(z_f, float(far))
    z_n = min(max(z_n, view.near), view.far)
    z_f = min(max(z_f, z_n * (1.0 + 1e-6)), view.far)
    return z_n, max(z_f, z_n * (1.0 + 1e-9))


def split_view(view: View, near: float, far: float) -> View:
    """The camera with its clip range (the projection's depth row: glOrtho's or glFrustum's) set to [near, far]."""
    rows = (ortho_matrix if view.orthographic else frustum_matrix)(-1.0, 1.0, -1.0, 1.0, near, far)[2:]
    return dataclasses.replace(view, projection=np.vstack([view.projection[:2], rows]), near=near, far=far)


def split_region(region: VisibleRegion, near: float, far: float) -> VisibleRegion:
    """``region`` between eye depths ``near`` and ``far`` (each tile's interval clipped)."""
    t = region.tiles
    tiles = dataclasses.replace(t, near=np.maximum(t.near, near), far=np.minimum(t.far, far))
    return VisibleRegion(tiles, region.source)
