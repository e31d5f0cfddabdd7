"""Lixel's math core: warped shadow-map parameterizations (numpy only, no bpy).

    setup = compute("lispsm", view, light, scene, WarpOptions())

The contract: docs/architecture.md; the papers' equations: docs/papers.md."""
from __future__ import annotations

import math
from contextlib import contextmanager

import numpy as np

from . import body as _body
from . import visibility as _visibility
from .body import IntersectionBody
from .methods import METHODS, SCENE_METHODS
from .types import (Diagnostics, EmptyBodyError, Light, Region, SceneBounds, ShadowMap, ShadowSetup, View,
                    WarpError, WarpOptions)
from .visibility import VisibleRegion, region_from_boxes

__all__ = ["compute", "METHODS", "intersection_body", "focused_body", "IntersectionBody", "VisibleRegion",
           "region_from_boxes", "View", "Light", "SceneBounds", "WarpOptions", "ShadowSetup", "ShadowMap", "Region",
           "Diagnostics", "WarpError", "EmptyBodyError"]


@contextmanager
def _warp_errors(what: str):
    """The core's error contract at a public entry: a ``ValueError`` or arithmetic
    error from deep in the geometry (degenerate input) becomes a ``WarpError``."""
    try:
        yield
    except WarpError:
        raise
    except (ValueError, ArithmeticError) as exc:
        raise WarpError(f"{what} cannot be computed for this camera, light and scene ({type(exc).__name__}: "
                        f"{exc}): check the camera's and the light's transforms and the camera's clip range") from exc


MAX_COORDINATE = 1e12
"""The largest coordinate (camera, light, box) the core takes, as far as it is tested: B and its tolerances are
relative to the camera and to what it sees (``body.intersection_body``), so a ground box of ±1e12 m gives its trimmed
twin's maps (tests/warp/test_limits.py); but there float64 carries only 1e-4 absolutely, millimetres no more."""


MIN_RESOLVED = 1e-9
"""The smallest view frustum (its bounding box's diagonal) relative to the camera's distance from the origin that the
core works with: below it float64 keeps fewer than about 1e7 steps across the frustum and the fits lose coverage."""


def _check_range(view: View, light: Light, scene: SceneBounds) -> None:
    """WarpError naming the input for coordinates beyond :data:`MAX_COORDINATE` or a
    view frustum below :data:`MIN_RESOLVED` where it is."""
    reach = scene.cached("max_coordinate", lambda: max(
        (float(np.abs(b).max()) for b in (scene.receivers, scene.casters) if b.size), default=0.0))
    checks = [("The scene's boxes", reach), ("The camera's position", max(map(abs, view.position.tolist())))]
    if light.position is not None:
        checks.append((f"The position of light '{light.name}'", max(map(abs, light.position.tolist()))))
    for what, value in checks:
        if value > MAX_COORDINATE:
            raise WarpError(f"{what} reaches {value:.3g} from the origin, beyond the {MAX_COORDINATE:.0e} Lixel can "
                            f"compute with: move the scene closer to the origin or scale it down")
    if why := unresolved_frustum(view):
        raise WarpError(f"The camera's view frustum {why}: widen its clip range or move the scene closer to the origin")


def unresolved_frustum(view: View, length=lambda v: f"{v:.3g}") -> str:
    """Why the view frustum is below :data:`MIN_RESOLVED` where it is, as ``length`` writes lengths ("" if not)."""
    extent = math.hypot(*(max(c) - min(c) for c in zip(*view.corners().tolist())))  # the frustum's box diagonal
    where = max(1.0, *map(abs, view.position.tolist()))
    return "" if extent >= MIN_RESOLVED * where else (f"is {length(extent)} across at {length(where)} from the "
                                                       f"origin, below what float64 resolves there")


def intersection_body(view: View, light: Light, scene: SceneBounds,
                      visible: VisibleRegion | None = None) -> IntersectionBody:
    """B (Scherzer §4.1) on the view frustum or focused on ``visible``. EmptyBodyError
    when nothing seen can be shadowed, WarpError for degenerate input."""
    _check_range(view, light, scene)
    with _warp_errors("The intersection body B"):
        return _body.intersection_body(view, light, scene, visible)


def focused_body(view: View, light: Light, scene: SceneBounds, options: WarpOptions | None = None,
                 visible: VisibleRegion | None = None) -> IntersectionBody:
    """B as ``options.focus`` says (``visibility.focused_body``). Errors as :func:`intersection_body`."""
    _check_range(view, light, scene)
    with _warp_errors("The intersection body B"):
        return _visibility.focused_body(view, light, scene, options, visible)


def compute(method: str, view: View, light: Light, scene: SceneBounds, options: WarpOptions | None = None,
            body: IntersectionBody | None = None, visible: VisibleRegion | None = None) -> ShadowSetup:
    """Light matrices for ``method``; B is :func:`focused_body` unless given (share it
    across methods). ``diagnostics.extra["focus"]`` says what B was fitted to."""
    if method not in METHODS:
        raise WarpError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    options = options or WarpOptions()
    if body is None:
        body = focused_body(view, light, scene, options, visible)
    with _warp_errors(f"The {method} light matrices"):         # (the cascade builds one B per split from the scene)
        setup = METHODS[method](view, light, body, options, *([scene] if method in SCENE_METHODS else []))
    if not all(np.isfinite(m.matrix).all() for m in setup.maps):
        raise WarpError(f"The {method} light matrices are not finite: check the camera's clip range and scene size")
    setup.diagnostics.extra["focus"] = body.focus
    if body.visible is not None:
        setup.diagnostics.extra["visible_depth_range"] = body.visible.depth_range
    return setup
