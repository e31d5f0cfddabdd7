"""The analytic aliasing model, one place for its formulas: the λ rules of the shared warp frustum in GMNPR's
2D model (§2-3, Fig. 4; θ ∈ [0, π/2] between light and view, φ half the field of view, λ = P_n / (P_f - P_n),
λ → ∞ the uniform map), Scherzer §4.4 Eq. 1, a map's raster Jacobian and Lloyd's perspective aliasing factor.
The model itself (Eq. 2's F, ψ, φ): tests/warp/aliasing_model.py; corrections and derivations: docs/papers.md."""
from __future__ import annotations

import math

import numpy as np

from .geometry import homogeneous

GLPR_FLOOR = 0.1
"""GLPR's λ never drops below this fraction of its ideal-case (θ = π/2) value n/(f - n)."""


# ---------------------------------------------------------------- the 2D model

def _t(theta: float, phi: float) -> float:
    """t = tan φ / tan θ (+inf at θ = 0)."""
    s = math.sin(theta)
    return math.tan(phi) * math.cos(theta) / s if s != 0.0 else math.inf


# ---------------------------------------------------------------- λ selections

def folded(gamma: float) -> float:
    """θ: γ ∈ [0, π] folded by symmetry into [0, π/2] (GMNPR's angles)."""
    return min(gamma, math.pi - gamma)


def lispsm_inverse_n_opt(z_n, delta_z, gamma) -> float:
    """1 / n_opt of Scherzer §4.4 Eq. 1, n_opt = (z_n + √(z_n(z_n + Δz))) / sin γ,
    finite for every γ (0 when light and view are parallel: the uniform map)."""
    z_n = max(float(z_n), 0.0)
    root = z_n + math.sqrt(z_n * (z_n + max(float(delta_z), 0.0)))
    return abs(math.sin(folded(gamma))) / root if root > 0.0 else math.inf    # (folded: exactly 0 at γ = π too)


def lambda_gmnpr(theta, n, f, phi) -> float:
    """GMNPR Eq. 8 (corrected Eq. 4/7, docs/papers.md): θ ≥ φ: λ1 =
    (n + √(fn) - n·t) / (f - n + (f + n)·t), t = tanφ/tanθ; θ < φ: λ2* = √(fn)/(2f) / tan(θπ/(4φ))."""
    if theta >= phi:
        t = _t(float(theta), phi)
        return (n + math.sqrt(f * n) - n * t) / (f - n + (f + n) * t)
    q = math.tan(theta * math.pi / (4.0 * phi))
    return math.inf if q <= 0.0 else math.sqrt(f * n) / (2.0 * f) / q


def lambda_glpr(theta, n, f, phi) -> float:
    """GLPR: F(z) ~ z -> λ = n(1 - t)/(f - n + (f + n)t), floored at ``GLPR_FLOOR``·n/(f - n);
    below θ = φ log-linear in θ to GMNPR's λ2* (∞ at θ = 0). Continuous (docs/papers.md)."""
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
    """GMNPR §3's (μ, ν): F(λ, n) = U·(λ + μ)²/(λ(λ + 1)), F(λ, f) = U·(n/f)·(λ + ν)²/(λ(λ + 1)),
    U the uniform map's aliasing at n."""
    theta = float(theta)
    ratio = math.tan(theta) / math.tan(phi) if theta < math.pi / 2 else math.inf    # tan θ / tan φ
    if theta >= phi:
        if not math.isfinite(ratio):
            return 0.0, 1.0
        d = (f - n) * ratio + f + n
        return n / d, 1.0 - f / d
    return 0.5 - (f - n) / (2.0 * f) * ratio, 0.5


def lambda_no_worse_than_uniform(theta, n, f, phi) -> float:
    """The least λ with max(F(λ, n), F(λ, f)) <= U: the warp's worst aliasing over
    [n, f] no worse than the uniform map's (the λ guard, part 1, docs/papers.md). ∞ when f <= n."""
    if not f > n:
        return math.inf
    mu, nu = end_offsets(theta, n, f, phi)
    near = mu * mu / (1.0 - 2.0 * mu) if mu < 0.5 else math.inf
    r = f / n
    b = r - 2.0 * nu
    far = 2.0 * nu * nu / (b + math.sqrt(b * b + 4.0 * (r - 1.0) * nu * nu)) if nu > 0 else 0.0   # the positive root
    return max(near, far)


def texel_ratios(lam, delta, body=None) -> list:
    """The warp's texel at λ (K, 1) over the uniform map's at δ ∈ [0, 1] along B's extent (N): along V_P,
    ρ = (λ + δ)²/(λ(λ + 1)), and, given B's vertices ``body`` = (δ, (q - q_eye)/D), its longer side (across:
    (1 + δ/λ)·range((q - q_eye)/(1 + δ/λ))/D) over uniform's (the λ guard, docs/papers.md). (K, N) each."""
    rho = lam + delta                   # (each step in place: numpy's (K, N) temporaries cost a fifth of the guard)
    rho **= 2
    rho /= lam * (lam + 1.0)
    if body is None or not np.ptp(body[1]) > 0:
        return [rho]
    across = delta / lam
    across += 1.0
    across *= np.ptp(body[1] / (1.0 + body[0] / lam), axis=1, keepdims=True)
    return [rho, np.divide(np.maximum(across, rho, out=across), max(float(np.ptp(body[1])), 1.0), out=across)]


def lambda_no_worse_on_average(delta, weights=None, body=None) -> float:
    """The least λ with E[ρ²] <= 1 over the visible pixels at δ (``delta``, ``weights``), along V_P and for the
    texel's longer side (:func:`texel_ratios`; the λ guard, part 2, docs/papers.md); ∞: none to 1e4."""
    d = np.clip(np.asarray(delta, dtype=np.float64), 0.0, 1.0)
    w = np.ones(len(d)) if weights is None else np.asarray(weights, dtype=np.float64)
    if not len(d) or not w.sum() > 0:
        return 0.0
    low, high = 1e-4, 1e4
    for _ in range(8):                                # each pass: the last λ that fails and the next, 80 steps finer
        grid = np.geomspace(low, high, 81)
        bad = np.flatnonzero(np.max([r ** 2 @ w for r in texel_ratios(grid[:, None], d, body)], axis=0) > w.sum())
        if not len(bad) or bad[-1] == len(grid) - 1:  # (first pass only: later ones bracket low fails, high holds)
            return math.inf if len(bad) else 0.0
        low, high = grid[bad[-1]], grid[bad[-1] + 1]
    return float(high)


def lambda_least_on_screen(delta, weights, depth, body=None) -> float:
    """The λ whose texels are least on screen over the visible pixels: argmin E[ρ/z], ρ the texel's longer side over
    uniform's (:func:`texel_ratios`) at each pixel's eye depth z (the λ guard, part 5, docs/papers.md); ∞: uniform."""
    d = np.clip(np.asarray(delta, dtype=np.float64), 0.0, 1.0)
    w = np.asarray(weights, dtype=np.float64) / np.asarray(depth, dtype=np.float64)
    grid = np.geomspace(1e-4, 1e4, 161)
    for refine in range(3):                           # each pass 40 steps finer around the least
        cost = texel_ratios(grid[:, None], d, body)[-1] @ w
        k = int(np.argmin(cost))
        if not cost[k] < w.sum() or (k == len(grid) - 1 and not refine):
            return math.inf
        least, grid = grid[k], np.geomspace(grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)], 41)
    return float(least)


# ---------------------------------------------------------------- raster densities

def raster_jacobian(matrix, size, points) -> np.ndarray:
    """(N, 2, 3) d(raster)/d(world) of the projective ``matrix`` onto a ``size`` raster (of a stack of (M, 4, 4) with
    (M, 2) sizes: (M, N, 2, 3)), D_M = diag(w, h)/2 · (M[:2, :3] - ndc ⊗ M[3, :3]) / w_clip. NaN where w_clip <= 0."""
    # Worked with the points along the last axis (..., 2, 3, N), then laid out as (..., N, 2, 3): numpy's elementwise
    # passes over runs of 3 cost 3x those over runs of N (the same operations on the same numbers: the same bits).
    m = np.asarray(matrix, dtype=np.float64)
    h = m @ homogeneous(points).T                                   # (..., 4, N)
    w = np.where(h[..., 3, :] > 0, h[..., 3, :], np.nan)
    ndc = h[..., :2, None, :] / w[..., None, None, :]
    d = (m[..., :2, :3, None] - ndc * m[..., None, 3, :3, None]) / w[..., None, None, :]
    half = np.asarray(size, dtype=np.float64)[..., :, None, None] / 2.0
    return np.moveaxis(d if np.all(half == 1.0) else d * half, -1, -3).copy()   # ((2, 2): NDC per metre, PSM's)


def pixel_density_constant(view) -> float:
    """K = R_x·R_y / (4·tanθ_x·tanθ_y) = R_x·R_y·P[0,0]·P[1,1]/4: pixels per unit area
    facing the camera at eye depth 1 (per unit area for an orthographic view)."""
    rx, ry = view.resolution
    p = view.projection
    return rx * ry * p[0, 0] * p[1, 1] / 4.0


def perspective_aliasing(view, light, matrix, size, points) -> np.ndarray:
    """Lloyd's m(p) of one map (``matrix`` onto a ``size`` raster) at (N, 3) world
    points; NaN where w <= 0 for the map. |det H⊥| = |(∇u × ∇v)·r| for the unit ray r (Binet-Cauchy)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    gradients = raster_jacobian(matrix, size, pts)                  # (N, 2, 3): ∇u, ∇v
    rays = light.direction if light.is_directional else light.rays_to(pts)
    given = np.abs(np.einsum("ij,ij->i", np.cross(gradients[:, 0], gradients[:, 1]), np.broadcast_to(rays, pts.shape)))
    k = pixel_density_constant(view)
    needed = np.full(len(pts), k) if view.orthographic else k / view.eye_depth(pts) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.sqrt(needed / given)
