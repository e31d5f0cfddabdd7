"""LiSPSM and its generalisations GMNPR and GLPR: one warp frustum, three λ rules.

* ``lispsm`` - Wimmer et al. with Scherzer §4.4: n_opt from Eq. 1, projection
  centre from Eq. 2, V_P from Eq. 3 (or B's middle vector), Δz from B or from
  the visible depth range, optional linear z (§4.2).
* ``gmnpr`` - Zhang et al.: the same frustum with λ from GMNPR Eq. 8,
  continuous at the critical angle θ = φ.
* ``glpr`` - the same frustum with F(z) ~ z (GMNPR §3, "GLPR").

The construction, the meaning of z_n, Δz, λ and φ, and the point-light and
degenerate cases are documented in :mod:`.warp_frustum`; the formulas live in
:mod:`..aliasing`.
"""
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
