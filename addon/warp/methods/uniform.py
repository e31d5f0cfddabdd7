"""Uniform (focused standard) shadow maps: the light frustum fitted to B (Scherzer §4.1); texel snapping (suns)
fits in a world-fixed frame with window sizes on a ladder and origins on whole texels, so edges do not crawl."""
from __future__ import annotations

from ..body import IntersectionBody
from ..types import Light, ShadowSetup, View, WarpOptions
from .common import body_diagnostics, uniform_setup


def uniform(view: View, light: Light, body: IntersectionBody, options: WarpOptions) -> ShadowSetup:
    return uniform_setup(view, light, body, options, body_diagnostics("uniform", view, light, body))
