"""Lixel's math core: warped shadow-map parameterizations (numpy only, no bpy).

    setup = compute("lispsm", view, light, scene, WarpOptions())

See docs/architecture.md for the contract and the papers in ../shared/papers.
"""
from __future__ import annotations

from .body import IntersectionBody, intersection_body
from .methods import METHODS
from .types import (Diagnostics, EmptyBodyError, Light, Region, SceneBounds, ShadowMap, ShadowSetup, View,
                    WarpError, WarpOptions)

__all__ = ["compute", "METHODS", "intersection_body", "IntersectionBody", "View", "Light", "SceneBounds",
           "WarpOptions", "ShadowSetup", "ShadowMap", "Region", "Diagnostics", "WarpError", "EmptyBodyError"]


def compute(method: str, view: View, light: Light, scene: SceneBounds, options: WarpOptions | None = None,
            body: IntersectionBody | None = None) -> ShadowSetup:
    """Light matrices for ``method``. B is computed unless given (share it across methods)."""
    if method not in METHODS:
        raise WarpError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    options = options or WarpOptions()
    if body is None:
        body = intersection_body(view, light, scene)
    return METHODS[method](view, light, body, options)
