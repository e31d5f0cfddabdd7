"""z-partitioning of the view (Scherzer §3: "a partitioning of the view frustum
into subsets and each subset is rendered into its own shadow map").

A cascade cuts the view's depth range [z_n, z_f] at eye depths

    z_n = C_0 < C_1 < ... < C_N = z_f

and gives split i the slab C_i <= eye depth <= C_(i+1) of the view frustum V.
The splits tile the range: each split starts where the previous one ends.

**The practical split scheme** (Zhang et al., *Parallel-Split Shadow Maps*,
PSSM; the scheme GMNPR's introduction and engines' cascades use) blends the
logarithmic split, whose depth ratio C_(i+1)/C_i is the same for every split
(the ideal for perspective aliasing), with the uniform split:

    C_i = λ·C_i^log + (1 - λ)·C_i^uni,   C_i^log = z_n·(z_f/z_n)^(i/N),
                                         C_i^uni = z_n + (z_f - z_n)·i/N.

**The depth range is tightened** to where a shadow can be seen: z_n is the
nearest visible receiver depth (``post_perspective.nearest_visible_depth``,
PSM §6's near plane "as far away as possible"), z_f the farthest depth of R =
V ∩ S_r ∩ L (what B is built from), both clipped to the visible region's depth
range (``visibility``: a depth pre-pass, or the scene's boxes ray-cast) and to
a caller's ``WarpOptions.visible_depth_range``. A split that starts at the
camera's near plane while the first visible receiver is 3 m away would spend
its texels, and its warp, on empty air.

**Each split sees its part of the visible region** (:func:`split_region`):
every screen tile's interval of visible depths clipped to the split's, so a
split's B holds what is visible in it, not all that the whole view sees within
its depths' slab.

Under a moving camera the tightened range moves every frame, and with it
every split boundary; a stable cascade widens it to whole octaves first
(``partition.stable``).
"""
from __future__ import annotations

import math

import numpy as np

from ..body import IntersectionBody
from ..post_perspective import nearest_visible_depth
from ..types import Light, View, WarpError, WarpOptions
from ..visibility import TileDepths, VisibleRegion

def practical_splits(z_n: float, z_f: float, count: int, lam: float) -> np.ndarray:
    """The PSSM split depths C_0..C_N (``count`` + 1 values, C_0 = z_n and C_N
    = z_f exactly): λ = 1 logarithmic, λ = 0 uniform."""
    if not 0.0 < z_n < z_f:
        raise WarpError(f"a cascade needs 0 < z_n < z_f (got {z_n}, {z_f})")
    if not 0.0 <= lam <= 1.0:
        raise WarpError(f"the split scheme's λ must be in [0, 1] (got {lam})")
    i_over_n = np.arange(count + 1) / count
    c_log = z_n * (z_f / z_n) ** i_over_n
    c_uni = z_n + (z_f - z_n) * i_over_n
    c = lam * c_log + (1.0 - lam) * c_uni
    c[0], c[-1] = z_n, z_f
    return c


def tightened_depth_range(view: View, light: Light, body: IntersectionBody,
                          options: WarpOptions) -> tuple[float, float]:
    """[z_n, z_f]: the eye depths between which a shadowed receiver can be
    seen (module docs), never outside the camera's clip range."""
    z_n = nearest_visible_depth(view, light, body)
    z_f = float(view.eye_depth(body.visible_vertices).max())
    if body.visible is not None:
        near, far = body.visible.depth_range
        z_n, z_f = max(z_n, near), min(z_f, far)
    if options.visible_depth_range is not None:
        near, far = options.visible_depth_range
        z_n, z_f = max(z_n, float(near)), min(z_f, float(far))
    z_n = min(max(z_n, view.near), view.far)
    z_f = min(max(z_f, z_n * (1.0 + 1e-6)), view.far)
    return z_n, max(z_f, z_n * (1.0 + 1e-9))


def with_clip_range(projection: np.ndarray, near: float, far: float, orthographic: bool) -> np.ndarray:
    """``projection`` with its depth row set for the clip range [near, far]
    (OpenGL, near -> z_ndc = -1): x, y and w (field of view, lens shift) are kept."""
    p = np.array(projection, dtype=np.float64)
    if orthographic:
        p[2, 2:] = -2.0 / (far - near), -(far + near) / (far - near)
    else:
        p[2, 2:] = -(far + near) / (far - near), -2.0 * far * near / (far - near)
    return p


def split_view(view: View, near: float, far: float) -> View:
    """The camera with its clip range narrowed to one split: the split's part
    of the view frustum V is this view's frustum."""
    projection = with_clip_range(view.projection, near, far, view.orthographic)
    return View(view.camera_to_world, projection, near, far, view.resolution, view.orthographic)


def split_region(region: VisibleRegion, near: float, far: float) -> VisibleRegion:
    """The part of a visible region between eye depths ``near`` and ``far``:
    each tile's interval clipped to [near, far] (empty where they do not meet)."""
    t = region.tiles
    tiles = TileDepths(t.x_edges, t.y_edges, np.maximum(t.near, near), np.minimum(t.far, far), t.samples)
    return VisibleRegion(tiles, region.source)
