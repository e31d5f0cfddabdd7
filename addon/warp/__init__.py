"""Lixel's math core: warped shadow-map parameterizations (numpy only, no bpy).

    setup = compute("lispsm", view, light, scene, WarpOptions())

See docs/architecture.md for the contract and the papers in ../shared/papers.
"""
from __future__ import annotations

from contextlib import contextmanager

from . import body as _body
from .body import IntersectionBody
from .methods import METHODS, SCENE_METHODS
from .types import (Diagnostics, EmptyBodyError, Light, Region, SceneBounds, ShadowMap, ShadowSetup, View,
                    WarpError, WarpOptions)

__all__ = ["compute", "METHODS", "intersection_body", "IntersectionBody", "View", "Light", "SceneBounds",
           "WarpOptions", "ShadowSetup", "ShadowMap", "Region", "Diagnostics", "WarpError", "EmptyBodyError"]


@contextmanager
def _warp_errors(what: str):
    """The core's error contract: whatever the input, a caller sees a result or a
    ``WarpError`` with a message. A plain ``ValueError`` (``numpy.linalg.LinAlgError``
    included) or an arithmetic error raised deep inside the geometry means the
    input is degenerate in a way the plain description did not catch; it is
    turned into a ``WarpError`` here, at the public entry."""
    try:
        yield
    except WarpError:
        raise
    except (ValueError, ArithmeticError) as exc:
        raise WarpError(f"{what} cannot be computed for this camera, light and scene ({type(exc).__name__}: "
                        f"{exc}): check the camera's and the light's transforms and the camera's clip range") from exc


def intersection_body(view: View, light: Light, scene: SceneBounds) -> IntersectionBody:
    """B, the intersection body (Scherzer §4.1). Raises ``EmptyBodyError`` when
    nothing the camera sees can be shadowed, ``WarpError`` for degenerate input."""
    with _warp_errors("The intersection body B"):
        return _body.intersection_body(view, light, scene)


def compute(method: str, view: View, light: Light, scene: SceneBounds, options: WarpOptions | None = None,
            body: IntersectionBody | None = None) -> ShadowSetup:
    """Light matrices for ``method``. B is computed unless given (share it across methods).
    Errors are ``WarpError`` (see :func:`intersection_body`)."""
    if method not in METHODS:
        raise WarpError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    options = options or WarpOptions()
    if body is None:
        body = intersection_body(view, light, scene)
    with _warp_errors(f"The {method} light matrices"):
        if method in SCENE_METHODS:         # the cascade builds one B per split from the scene
            return METHODS[method](view, light, body, options, scene)
        return METHODS[method](view, light, body, options)
