"""Plane-optimal shadow maps (Chong & Gortler, "A Lixel for every Pixel", EGSR 2004).

Work in progress: the full construction lands in the next commits.
"""
from __future__ import annotations

from ..body import IntersectionBody
from ..types import Light, ShadowSetup, View, WarpError, WarpOptions


def plane_optimal(view: View, light: Light, body: IntersectionBody, options: WarpOptions) -> ShadowSetup:
    raise WarpError("plane_optimal is not available yet in this build")
