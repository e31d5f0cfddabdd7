"""GMNPR's 2D perspective-aliasing model (Zhang et al., §2-3, Fig. 4), the
reference the λ rules of ``addon/warp/aliasing.py`` are checked against:
F(λ, θ, z) = ψ(λ, θ)·(z + φ(λ, θ))²/z (Eq. 2), the map coordinate it is derived
from, the view frustum's extent along V_P and LiSPSM's λ (Eq. 9). See that
module's docstring for the notation."""
from __future__ import annotations

import math

import numpy as np

from addon.warp.aliasing import lispsm_inverse_n_opt


def _t(theta, phi):
    """t = tan φ / tan θ (+inf at θ = 0)."""
    theta = np.asarray(theta, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.tan(phi) * np.cos(theta) / np.sin(theta)


def model_extent(theta, n, f, phi):
    """P_f - P_n: the view frustum's extent along V_P (GMNPR Eq. 9's denominator).

    θ ≥ φ: sin θ·(f - n) + cos θ·tan φ·(f + n);  θ ≤ φ: 2 f cos θ tan φ.
    Continuous at θ = φ (both 2 f sin φ)."""
    theta = np.asarray(theta, dtype=np.float64)
    tp = math.tan(phi)
    case1 = np.sin(theta) * (f - n) + np.cos(theta) * tp * (f + n)
    case2 = 2.0 * f * np.cos(theta) * tp
    return np.where(theta >= phi, case1, case2)


def model_near_side(theta, n, f, phi):
    """Where the view frustum starts along V_P, measured from the eye:
    n(sin θ - cos θ tan φ) for θ ≥ φ, f(sin θ - cos θ tan φ) below."""
    theta = np.asarray(theta, dtype=np.float64)
    s = np.sin(theta) - np.cos(theta) * math.tan(phi)
    return np.where(theta >= phi, n * s, f * s)


def psi(lam, theta, n, f, phi):
    """ψ(λ, θ) of GMNPR Eq. 2.

    θ < φ: 1 / (tan φ · 2fλ(λ + 1) · tan φ/tan θ). The extracted text prints the
    last factor as tan θ/tan φ; that contradicts the paper's own Case 2 values of
    F(λ, θ, n) and F(λ, θ, f) (§3) and the geometry of Fig. 4, which both give
    tan φ/tan θ (tests/warp/test_aliasing.py checks all three agree)."""
    theta = np.asarray(theta, dtype=np.float64)
    t = _t(theta, phi)
    with np.errstate(divide="ignore", invalid="ignore"):
        case1 = 1.0 / (math.tan(phi) * (f - n + (f + n) * t) * lam * (lam + 1.0))
        case2 = 1.0 / (math.tan(phi) * 2.0 * f * lam * (lam + 1.0) * t)
    return np.where(theta >= phi, case1, case2)


def varphi(lam, theta, n, f, phi):
    """φ(λ, θ) of GMNPR Eq. 2 (the offset of the hyperbola's pole in eye depth)."""
    theta = np.asarray(theta, dtype=np.float64)
    t = _t(theta, phi)
    with np.errstate(invalid="ignore"):
        case1 = (f - n + (f + n) * t) * lam + n * t - n
        case2 = f * (2.0 * lam + 1.0) * t - f
    return np.where(theta >= phi, case1, case2)


def uniform_F(theta, z, n, f, phi):
    """F of the uniform map (the λ → ∞ limit of Eq. 2): (P_f - P_n)/(z sin θ tan φ)."""
    theta = np.asarray(theta, dtype=np.float64)
    with np.errstate(divide="ignore"):
        return model_extent(theta, n, f, phi) / (np.asarray(z, dtype=np.float64) * np.sin(theta) * math.tan(phi))


def aliasing_F(lam, theta, z, n, f, phi):
    """GMNPR Eq. 2: F(λ, θ, z) = ψ(λ, θ)·(z + φ(λ, θ))²/z; λ = inf gives :func:`uniform_F`."""
    lam = np.asarray(lam, dtype=np.float64)
    z = np.asarray(z, dtype=np.float64)
    finite = np.isfinite(lam)
    lam_f = np.where(finite, lam, 1.0)
    with np.errstate(invalid="ignore", over="ignore"):
        warped = psi(lam_f, theta, n, f, phi) * (z + varphi(lam_f, theta, n, f, phi)) ** 2 / z
    return np.where(finite, warped, uniform_F(theta, z, n, f, phi))


def map_coordinate(lam, theta, z, n, f, phi):
    """s(z) ∈ [0, 1]: P's hyperbolic depth of the central-ray point at eye depth z
    (s = (1 + λ)(1 - λ/d), d = its distance from P's centre in units of the
    extent). The geometric definition Eq. 2 is derived from: F = dz/(z ds)/tan φ."""
    theta = np.asarray(theta, dtype=np.float64)
    d = (np.asarray(z) * np.sin(theta) - model_near_side(theta, n, f, phi)) / model_extent(theta, n, f, phi) + lam
    return (1.0 + lam) * (1.0 - lam / d)


def lambda_lispsm(theta, n, f, phi) -> float:
    """GMNPR Eq. 9: λ_LiSPSM = n_opt / (P_f - P_n) with Eq. 1's z_n = n, Δz = f - n."""
    k = lispsm_inverse_n_opt(n, f - n, theta)
    ext = float(model_extent(theta, n, f, phi))
    return math.inf if k == 0.0 else 1.0 / (k * ext)
