"""The analytic aliasing model: one place for its formulas (numpy only).

Two parts.

**1. GMNPR's perspective-aliasing model** (Zhang et al., *Generalized
Minimum-Norm Perspective Shadow Maps*, §2-3; the computational model of their
Fig. 4). A directional light, the 2D plane spanned by the view and light
directions; the view frustum has near ``n``, far ``f`` and half field of view
``phi`` in that plane; ``theta`` in [0, π/2] is the angle between the light and
view directions (folded by symmetry). The warp frustum P looks along V_P (the
view direction projected perpendicular to the light, LiSPSM's Eq. 3) and covers
the view frustum's extent along V_P, ``P_f - P_n``.
λ = P_n / (P_f - P_n) is P's near distance in units of that extent. A point on
the central view ray at eye depth z sits at z·sin θ along V_P; the map
coordinate is P's hyperbolic depth s ∈ [0, 1], and

    F(λ, θ, z) = (1 / tan φ) · dz / (z · ds) = ψ(λ, θ) · (z + φ(λ, θ))² / z          (Eq. 2)

is the perspective aliasing (screen pixels per texel along z, up to the
resolutions). λ → ∞ is the uniform map. The model itself (F, ψ, φ, the map
coordinate, the extent) is what the tests check the λ rules against, so it
lives with them: ``tests/warp/aliasing_model.py``.

The λ selections, each a function of (θ, n, f, φ):

* :func:`lambda_gmnpr` - GMNPR Eq. 8 (Eq. 4's λ1 for θ ≥ φ, Eq. 7's λ2* below;
  continuous at θ = φ where both are √(fn)/(2f); README corrections applied).
* LiSPSM's λ, GMNPR Eq. 9 (Scherzer Eq. 1's n_opt with z_n = n, Δz = f - n,
  divided by the extent, ``aliasing_model.lambda_lispsm`` in the tests; the
  method itself uses :func:`lispsm_inverse_n_opt`).
* :func:`lambda_glpr` - GLPR: F(z) ~ z, i.e. φ(λ, θ) = 0 in Eq. 2 (the warp's
  projection centre at the eye's position along V_P, PSM's choice). That λ is
  n(1 - t)/(f - n + (f + n)t), t = tan φ / tan θ, which is 0 at θ = φ and has no
  positive solution below (GMNPR §3: "λ = 0 is obviously disastrous"). GLPR's
  paper is not in our corpus, so Lixel keeps it usable the way GMNPR treats its
  own degenerate range (Eq. 5-7): λ is floored at ``GLPR_FLOOR`` times its
  ideal-case value n/(f - n), and for θ < φ it moves log-linearly in θ from that
  floor (at φ) to GMNPR's λ2* (Eq. 7), reaching ∞ at θ = 0 (convergence to the
  uniform map) no more abruptly than GMNPR does.

:func:`lambda_no_worse_than_uniform` and :func:`lambda_no_worse_on_average` are
GLPR's guard: the least λ at which the warp's worst aliasing over the depths
[n, f] is no worse than the uniform map's worst, and at which its aliasing over
the visible pixels, in the L2 norm of its ratio to the uniform map's, is no
worse either (GMNPR §3 warns that GLPR "might be over-strong"; docs/papers.md
derives both).

:func:`lispsm_inverse_n_opt` is Scherzer §4.4 Eq. 1 written as 1 / n_opt, finite
for every γ (0 at γ = 0, the uniform limit).

**2. The per-point texel footprint** of a real map (any ShadowMap matrix, any
View): at a surface point p with normal N, both the screen and the map
parameterize the surface. With T = [t1 t2] an orthonormal tangent basis and,
for a projective 4x4 matrix M onto an R_x x R_y raster,

    D_M(p) = diag(R_x, R_y)/2 · (M[:2, :3] - ndc ⊗ M[3, :3]) / w        (d raster / d world)

G = D_view·T (pixels per unit length on the surface), H = D_map·T (texels per
unit length). J = H·G⁻¹ is d texel / d pixel; the **footprint** reported is

    1 / σ_min(J) = σ_max(G·H⁻¹)

the screen length, in pixels, of one texel step in its worst direction
(Lloyd's per-point aliasing factor m; Stamminger-Drettakis §1.1's
dp = ds·r_s·cosβ/(r_i·cosα) is its 1D form). Above 1, texels are magnified on
screen. :func:`texel_footprint_area` gives |det G| / |det H|, pixels per texel
by area. A surface edge-on to the map (H singular: projection aliasing) gives
+inf; a point behind the camera or the map (w <= 0) gives NaN.

**3. Lloyd's perspective aliasing factor** (:func:`perspective_aliasing`),
the per-point quantity his physical limit m_min = sqrt(N_min / N) bounds
(``addon/measure/lloyd.py``): both densities per unit area on the plane
through p perpendicular to the light ray, so the surface's orientation
(projection aliasing, which no warp changes) drops out,

    m(p) = sqrt(K / z(p)² / |det H⊥(p)|),   K = R_x·R_y / (4·tanθ_x·tanθ_y),

with z the eye depth (K alone for an orthographic view) and H⊥ the map's
raster Jacobian on that plane. For a sun and any map that is a projection
from the light, |det H⊥| = c / w³ with w the map's clip w, so m² = K·w³/(c·z²)
is convex in the point (w and z are affine, w³/z² is the perspective of w³):
its maximum over a convex region lies at a vertex.
"""
from __future__ import annotations

import math

import numpy as np

from .geometry import homogeneous

GLPR_FLOOR = 0.1
"""GLPR's λ never drops below this fraction of its ideal-case (θ = π/2) value n/(f - n)."""


# ---------------------------------------------------------------- the 2D model

def _t(theta, phi):
    """t = tan φ / tan θ (0 at θ = π/2, +inf at θ = 0); a float for a float θ
    (the λ rules, once per frame), an array otherwise (the model's curves)."""
    if isinstance(theta, float):
        s = math.sin(theta)
        return math.tan(phi) * math.cos(theta) / s if s != 0.0 else math.inf
    theta = np.asarray(theta, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.tan(phi) * np.cos(theta) / np.sin(theta)


# ---------------------------------------------------------------- λ selections

def folded(gamma: float) -> float:
    """θ, GMNPR's angle between the light and view directions: γ ∈ [0, π]
    folded by symmetry into [0, π/2]."""
    return min(gamma, math.pi - gamma)


def lispsm_inverse_n_opt(z_n, delta_z, gamma) -> float:
    """1 / n_opt of Scherzer §4.4 Eq. 1, n_opt = (z_n + √(z_n(z_n + Δz))) / sin γ.

    Written as sin γ / (z_n + √(z_n(z_n + Δz))) so it is finite for every γ:
    0 when light and view are parallel (n_opt = ∞, the uniform map)."""
    z_n = max(float(z_n), 0.0)
    root = z_n + math.sqrt(z_n * (z_n + max(float(delta_z), 0.0)))
    if root <= 0.0:
        return math.inf
    return abs(math.sin(folded(gamma))) / root    # (folded: exactly 0 at γ = π too)


def lambda_gmnpr(theta, n, f, phi) -> float:
    """GMNPR Eq. 8 (with the README's corrected Eq. 4/7): θ ≥ φ:
    λ1 = (n + √(fn) - n·tanφ/tanθ) / (f - n + (f + n)·tanφ/tanθ);
    θ < φ: λ2* = √(fn)/(2f) / tan(θπ/(4φ)) (∞ at θ = 0)."""
    if theta >= phi:
        t = _t(float(theta), phi)
        return (n + math.sqrt(f * n) - n * t) / (f - n + (f + n) * t)
    q = math.tan(theta * math.pi / (4.0 * phi))
    return math.inf if q <= 0.0 else math.sqrt(f * n) / (2.0 * f) / q


def lambda_glpr(theta, n, f, phi) -> float:
    """GLPR: F(z) ~ z, φ(λ, θ) = 0 -> λ = n(1 - t)/(f - n + (f + n)t), floored at
    ``GLPR_FLOOR``·n/(f - n); below θ = φ, log-linear in θ from that floor (at φ)
    to GMNPR's λ2* (Eq. 7, ∞ at θ = 0). Continuous everywhere."""
    floor = GLPR_FLOOR * n / max(f - n, 1e-300 * max(n, 1.0))
    if theta >= phi:
        t = _t(float(theta), phi)
        return max(n * (1.0 - t) / (f - n + (f + n) * t), floor)
    g = lambda_gmnpr(theta, n, f, phi)
    if not math.isfinite(g):
        return math.inf
    w = theta / phi
    return math.exp(w * math.log(floor) + (1.0 - w) * math.log(g))


def end_offsets(theta, n, f, phi) -> tuple[float, float]:
    """GMNPR §3's (μ, ν): with them the aliasing at the two ends of [n, f] is

        F(λ, θ, n) = U · (λ + μ)² / (λ(λ + 1)),   F(λ, θ, f) = U · (n/f) · (λ + ν)² / (λ(λ + 1)),

    U = F(∞, θ, n) the uniform map's aliasing at n (its worst: uniform F ~ 1/z).
    θ ≥ φ: μ = n / ((f - n) tanθ/tanφ + f + n), ν = 1 - f / ((f - n) tanθ/tanφ + f + n);
    θ < φ: μ = 1/2 - (f - n)/(2f) · tanθ/tanφ, ν = 1/2."""
    theta = float(theta)
    ratio = math.tan(theta) / math.tan(phi) if theta < math.pi / 2 else math.inf    # tan θ / tan φ
    if theta >= phi:
        if not math.isfinite(ratio):
            return 0.0, 1.0
        d = (f - n) * ratio + f + n
        return n / d, 1.0 - f / d
    return 0.5 - (f - n) / (2.0 * f) * ratio, 0.5


def lambda_no_worse_than_uniform(theta, n, f, phi) -> float:
    """The least λ whose worst aliasing over [n, f] is no worse than the uniform
    map's worst, max(F(λ, n), F(λ, f)) <= U (GMNPR Eq. 2 at the ends,
    :func:`end_offsets`; F is convex in z, so its maximum over [n, f] is at an
    end). The near end needs (λ + μ)² <= λ(λ + 1), i.e. λ >= μ² / (1 - 2μ);
    the far end (λ + ν)² <= r λ(λ + 1) with r = f/n, i.e. λ at least the
    positive root of (r - 1)λ² + (r - 2ν)λ - ν² = 0. In the ideal case
    (θ = π/2: μ = 0, ν = 1) this is n / (f - n), GLPR's own λ, where GLPR's
    far-end aliasing equals the uniform map's near-end aliasing exactly; at any
    other angle GLPR's λ is below it. GMNPR's λ1 (θ >= φ, the minimax over
    [n, f]) satisfies it; its λ2* below φ (Eq. 7, a heuristic) need not. ∞
    (only the uniform map) when f <= n."""
    if not f > n:
        return math.inf
    mu, nu = end_offsets(theta, n, f, phi)
    near = mu * mu / (1.0 - 2.0 * mu) if mu < 0.5 else math.inf
    r = f / n
    b = r - 2.0 * nu
    far = 2.0 * nu * nu / (b + math.sqrt(b * b + 4.0 * (r - 1.0) * nu * nu)) if nu > 0 else 0.0   # the positive root
    return max(near, far)


def lambda_no_worse_on_average(delta, weights=None) -> float:
    """The least λ at which the warp's aliasing over the visible pixels, in the
    L2 norm of its ratio to the uniform map's, is no worse than the uniform
    map's (GMNPR §3: "we can define variant norms"; GMNPR itself minimizes the
    L∞ norm along the view direction).

    A pixel whose surface point lies at δ ∈ [0, 1] along B's extent on V_P
    (δ = (h - h_min)/D, the warp's own depth coordinate) sees the warp's
    texels along V_P at ρ(δ) = (λ + δ)²/(λ(λ + 1)) times the uniform map's
    (the map coordinate s = (1 + λ)(1 - λ/(δ + λ)) has ds/dδ = λ(1 + λ)/(δ + λ)²;
    the uniform map's ds/dδ is 1). Requiring E[ρ²] <= 1 over the pixels
    (``delta`` weighted by the pixels each sample stands for) is, with the
    moments m_k = E[δ^k],

        p(λ) = (4m₁ - 2)λ³ + (6m₂ - 1)λ² + 4m₃λ + m₄ <= 0,

    true for every λ beyond the largest positive root of p when m₁ < 1/2 (its
    leading coefficient is negative) and for none otherwise (∞: with most
    pixels in B's far half along V_P no warp wins). The mean of ρ (the L1
    norm) would let a few pixels' texels grow tenfold for the many near ones'
    gain; rendered shadows lose exactly there (small far casters vanish), so
    the L2 norm, which weighs large losses more, is the guard."""
    d = np.clip(np.asarray(delta, dtype=np.float64), 0.0, 1.0)
    w = np.ones(len(d)) if weights is None else np.asarray(weights, dtype=np.float64)
    total = float(w.sum())
    if not len(d) or not total > 0:
        return 0.0
    m1, m2, m3, m4 = (float(w @ d ** k) / total for k in (1, 2, 3, 4))
    if not m1 < 0.5:
        return math.inf
    roots = np.roots([4.0 * m1 - 2.0, 6.0 * m2 - 1.0, 4.0 * m3, m4])
    real = roots.real[(np.abs(roots.imag) <= 1e-9 * np.maximum(1.0, np.abs(roots.real))) & (roots.real > 0)]
    return float(real.max()) if len(real) else 0.0


# ---------------------------------------------------------------- texel footprint

def tangent_basis(normals) -> np.ndarray:
    """(N, 3, 2): two orthonormal tangent vectors per normal."""
    nrm = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    nrm = nrm / np.linalg.norm(nrm, axis=1, keepdims=True)
    helper = np.where(np.abs(nrm[:, :1]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    t1 = np.cross(nrm, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(nrm, t1)
    return np.stack([t1, t2], axis=2)


def raster_jacobian(matrix, size, points) -> np.ndarray:
    """(N, 2, 3) d(raster)/d(world) of the projective ``matrix`` onto a ``size`` =
    (w, h) raster (raster x = (ndc_x + 1)/2·w). NaN where w <= 0."""
    m = np.asarray(matrix, dtype=np.float64)
    h = homogeneous(points) @ m.T
    w = h[:, 3]
    w = np.where(w > 0, w, np.nan)
    ndc = h[:, :2] / w[:, None]
    d = (m[None, :2, :3] - ndc[:, :, None] * m[None, 3:4, :3]) / w[:, None, None]
    scale = np.array([size[0], size[1]], dtype=np.float64) / 2.0
    return d * scale[None, :, None]


def _surface_jacobians(view, shadow_map, points, normals):
    t = tangent_basis(normals)
    g = raster_jacobian(view.world_to_clip, view.resolution, points) @ t     # pixels per length
    h = raster_jacobian(shadow_map.matrix, shadow_map.size, points) @ t      # texels per length
    return g, h


def texel_footprint(view, shadow_map, points, normals) -> np.ndarray:
    """Screen pixels per texel, linear, at (N, 3) surface ``points`` with ``normals``:
    σ_max(G·H⁻¹) = 1/σ_min(d texel / d pixel). +inf where the surface is edge-on
    to the map, NaN where w <= 0 for the camera or the map."""
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


def pixel_density_constant(view) -> float:
    """K = R_x·R_y / (4·tanθ_x·tanθ_y): pixels per unit area on a surface facing
    the camera at eye depth 1 (perspective), or per unit area for an
    orthographic view. Read from the projection matrix: an image plane at unit
    depth spans 2/P[0,0] by 2/P[1,1] (lens shift does not change its area)."""
    rx, ry = view.resolution
    p = view.projection
    return rx * ry * p[0, 0] * p[1, 1] / 4.0


def perspective_aliasing(view, light, matrix, size, points) -> np.ndarray:
    """Lloyd's perspective aliasing factor m(p) of one map (``matrix`` onto a
    ``size`` raster) at (N, 3) world points (module docs, part 3). NaN where
    w <= 0 for the map.

    The texels per unit area across the light ray, |det H⊥|, need no tangent
    basis: for raster gradients ∇u, ∇v and an orthonormal basis (t1, t2) of the
    plane across the unit ray r, det [∇u·t_j; ∇v·t_j] = (∇u × ∇v)·(t1 × t2) =
    (∇u × ∇v)·r (Binet-Cauchy)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    gradients = raster_jacobian(matrix, size, pts)                  # (N, 2, 3): ∇u, ∇v
    rays = light.direction if light.is_directional else light.rays_to(pts)
    given = np.abs(np.einsum("ij,ij->i", np.cross(gradients[:, 0], gradients[:, 1]), np.broadcast_to(rays, pts.shape)))
    k = pixel_density_constant(view)
    needed = np.full(len(pts), k) if view.orthographic else k / view.eye_depth(pts) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.sqrt(needed / given)


def setup_texel_footprint(view, setup, points, normals) -> np.ndarray:
    """:func:`texel_footprint` of a ShadowSetup: each point measured in the map
    that serves it (``setup.map_index``); NaN for points no map serves."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    nrm = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    idx = setup.map_index(pts, view)
    out = np.full(len(pts), np.nan)
    for i, m in enumerate(setup.maps):
        sel = idx == i
        if sel.any():
            out[sel] = texel_footprint(view, m, pts[sel], nrm[sel])
    return out
