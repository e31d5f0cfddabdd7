"""LiSPSM and its generalisations: one warp frustum (:mod:`.warp_frustum`), three λ rules (:mod:`..aliasing`):
``lispsm`` (Wimmer et al. with Scherzer §4.4, Eq. 1-3), ``gmnpr`` (GMNPR Eq. 8), ``glpr`` (F(z) ~ z, GMNPR §3)."""
from __future__ import annotations

from ..body import IntersectionBody
from ..types import Light, ShadowSetup, View, WarpOptions
from .warp_frustum import rule_glpr, rule_gmnpr, rule_lispsm, warped_setup


def lispsm(view: View, light: Light, body: IntersectionBody, options: WarpOptions) -> ShadowSetup:
    """Light space perspective shadow map, n_opt = (z_n + √(z_n(z_n + Δz))) / sin γ."""
    return warped_setup("lispsm", rule_lispsm, view, light, body, options)


def gmnpr(view: View, light: Light, body: IntersectionBody, options: WarpOptions) -> ShadowSetup:
    """Generalized minimum-norm perspective reparameterization (GMNPR Eq. 8)."""
    return warped_setup("gmnpr", rule_gmnpr, view, light, body, options)


def glpr(view: View, light: Light, body: IntersectionBody, options: WarpOptions) -> ShadowSetup:
    """Generalized linear perspective reparameterization: F(z) ~ z."""
    return warped_setup("glpr", rule_glpr, view, light, body, options)
