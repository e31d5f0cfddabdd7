"""Perspective shadow maps (Stamminger & Drettakis, SIGGRAPH 2002): world -> virtual camera clip (§4.2, §6)
-> the PPS light's frustum (§3) -> the unit-cube fit (§4), with the pieces in ``post_perspective.py``.
Where PSM hands over to the uniform map: docs/papers.md, "The warp core's derivations"."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from ..aliasing import raster_jacobian
from ..body import IntersectionBody
from ..diagnostics import Diagnostics
from ..fit import fit_to_unit_cube
from ..frame import LightFrame, light_frames
from ..geometry import finite_clip_volume_corners, transform_points, translation
from ..linear_depth import light_depth_row
from ..post_perspective import PPSLight, VirtualCamera, nearest_visible_depth, pps_light_matrix, virtual_camera
from ..types import Light, ShadowMap, ShadowSetup, View, WarpOptions
from .common import body_diagnostics, uniform_setup
from .warp_frustum import edge_turned, eye_depth_range, guard_lambda, light_at_eye, map_lambda

COVER_TOLERANCE = 1e-6
"""Final check: every B vertex has |NDC| <= 1 + this (the fit pads by 1e-7)."""
GUARD_STEPS = 16
"""At most this many virtual cameras are tried when the λ guard moves PSM's back."""
GUARD_FAR = 1e6
"""The guard's search hands over to the uniform map rather than move the virtual camera this many
depths of B back (λ ≈ 1e6 for a sun across the view: the uniform map to float precision)."""
GUARD_TOLERANCE = 1e-3
"""The guard's search aims PSM's λ at most this much (relative) above the guard's λ."""


@dataclass(frozen=True)
class PSMWarp:
    """PSM's map for one virtual camera: the camera, its PPS light frustum, the fitted camera-relative map (or None)."""

    camera: VirtualCamera
    light_in_pps: PPSLight
    relative: Optional[np.ndarray]


def psm(view: View, light: Light, body: IntersectionBody, options: WarpOptions) -> ShadowSetup:
    """World -> light clip by the paper's pipeline (§3, §4.2, §4, §6), guarded by ``guarded_warp``."""
    diag = body_diagnostics("psm", view, light, body)
    if view.orthographic:
        return _uniform_fallback(view, light, body, options, diag, "orthographic camera",
                                 "the post-perspective space of an orthographic camera is affine: "
                                 "PSM equals the uniform map")
    if not light.is_directional and bool(body.contains(light.position[None])[0]):
        return _uniform_fallback(view, light, body, options, diag, "light inside B",
                                 f"light '{light.name}' is inside the region that must be covered: no single "
                                 "frustum in post-perspective space contains it; using the uniform cube faces")
    frames = light_frames(view, light, body, options)
    warp = psm_warp(view, light, body, options, nearest_visible_depth(view, light, body, options), frames)
    if warp.relative is None:                                          # (§3: no single frustum from L' holds B')
        diag.extra.update(_pps_report(warp))
        half = math.degrees(warp.light_in_pps.cone_half_angle)
        why = (f"touches B in post-perspective space (cone half-angle {half:.4f} deg): no single frustum"
               if not warp.light_in_pps.single_frustum else f"needs a {2 * half:.0f} deg frustum in post-perspective "
               f"space (max {math.degrees(options.max_frustum_angle):.0f}); using the uniform map's cube faces")
        return _uniform_fallback(view, light, body, options, diag, "PPS light frustum", f"light '{light.name}' {why}")
    if options.lambda_guard == "all":
        warp, note = guarded_warp(view, light, body, options, warp, diag, frames)
        if warp is None:
            return _uniform_fallback(view, light, body, options, diag, "main: λ guard", note)
        if note:
            diag.fallback("main: λ guard", note)
    diag.extra.update(_pps_report(warp))
    shadow_map = ShadowMap(warp.relative @ translation(-view.position), options.shadow_map_size, "LESS", "main")
    if not shadow_map.contains(body.vertices, COVER_TOLERANCE).all():
        return _uniform_fallback(view, light, body, options, diag, "PSM matrix",
                                 "the composed PSM matrix is not finite or does not cover B (numerically degenerate)")
    diag.warp_frustum_corners = finite_clip_volume_corners(warp.relative, view.position)
    diag.extra.update(psm_applied=True, frames=["main"])
    if options.linear_z:
        shadow_map.depth_row = light_depth_row(light, body)
        if shadow_map.depth_row is None:
            diag.fallback("linear z", "B surrounds the light too widely for one depth axis (89°); hyperbolic depth")
    return ShadowSetup([shadow_map], diag)


def psm_warp(view: View, light: Light, body: IntersectionBody, options: WarpOptions, visible_near: float,
             frames: list[LightFrame]) -> PSMWarp:
    """The virtual camera, near at ``visible_near`` (§4.2, §6), its PPS light frustum around B' (§3), the fit (§4),
    its x, y turned towards the light frame's where the light has one (``turned_fit``)."""
    camera = virtual_camera(view, body, visible_near)
    light_in_pps = pps_light_matrix(camera.to_pps @ light.homogeneous_from(view.position), camera.points,
                                    math.inf if light.is_directional else options.max_frustum_angle / 2)
    frame = frames[0] if len(frames) == 1 else None
    return PSMWarp(camera, light_in_pps, None if light_in_pps.matrix is None
                   else turned_fit(light_in_pps.matrix @ camera.to_pps, view, body, frame))


def turned_fit(unfitted: np.ndarray, view: View, body: IntersectionBody, frame: Optional[LightFrame]) -> np.ndarray:
    """The fit (§4) of ``unfitted`` (camera-relative world -> the PPS light's clip), its x, y turned from PPS's towards
    ``frame``'s as far as that shrinks the texel at B's centroid, fully from half its area. PPS scales the view's x, y
    and depth unlike, so x, y square in PPS can be skewed in the light's image; turned, PSM tends to the uniform map
    as the virtual camera moves back, as §4.2 says it must (docs/papers.md, "PSM's map axes under a low sun").
    J: a fitted map's d(x/w, y/w) over the frame's x, y at B's centroid; C = J⁻¹ at det 1 puts the fitted x, y along
    the frame's there; the turn is I + t (C - I), t = log2 of the texel's area before over after, clamped to [0, 1].
    Then turned about its depth axis off the first look's shadow edges, if any (``edge_turned``)."""
    fitted = lambda m: fit_to_unit_cube(m, body.vertices - view.position)
    jacobian = lambda m: raster_jacobian(m @ translation(-view.position) @ np.linalg.inv(frame.to_light), (2, 2),
                                         transform_points(frame.to_light, body.volume_centroid))[..., 0, :, :2]
    relative = fitted(unfitted)
    if frame is None or not np.linalg.det(j := jacobian(relative)) > 0:
        return relative
    c = np.linalg.inv(j) * math.sqrt(np.linalg.det(j))
    turned = lambda t: fitted(np.vstack([((1 - t) * np.eye(2) + t * c) @ relative[:2], relative[2:]]))
    t = min(math.log2(max(np.linalg.det(jacobian(turned(1.0))) / np.linalg.det(j), 1.0)), 1.0)
    relative = turned(t) if t > 0 else relative
    return edge_turned(relative, body.vertices - view.position, body, translation(-view.position))


def guarded_warp(view: View, light: Light, body: IntersectionBody, options: WarpOptions, warp: PSMWarp,
                 diag: Diagnostics, frames: list[LightFrame]) -> tuple[Optional[PSMWarp], str]:
    """The λ guard (docs/papers.md) for PSM: the virtual near distance rises until PSM's λ (``map_lambda``) is
    within ``GUARD_TOLERANCE`` above the guard's (§4.2: at infinity PSM is the uniform map). Returns the warp and
    why it moved ("": it did not), or None and why the uniform map serves."""
    at, _ = light_at_eye(view, light, options, body, view.direction)
    if len(frames) != 1 or at is None:
        return warp, ""
    ctx = eye_depth_range(view, body, options, diag, at)
    axis, lam = map_lambda(warp.relative @ translation(-view.position), frames[0])
    guard, why = guard_lambda(lam, at.gamma, axis, ctx) if axis is not None else (lam, None)
    if not why:
        return warp, ""
    aim = 1.0 + GUARD_TOLERANCE / 2                                   # λ / the guard's λ aimed at
    tried_points, low, high = [(0.0, 0.0), (warp.camera.near, lam / guard)], warp.camera.near, None
    for _ in range(GUARD_STEPS):                                      # (the first step: λ ∝ near)
        (x0, y0), (x, y) = tried_points[-2:]
        if not y > 0.0:                                               # the guard's λ is ∞
            return None, f"PSM's {why}; along its axis no warp is no worse than the uniform map"
        x += (aim - y) * ((x - x0) / (y - y0) if y > y0 else x / y)
        if high is not None and not low < x < high:
            x = (low + high) / 2
        if not x < GUARD_FAR * (warp.camera.far - warp.camera.near):
            return None, f"PSM's {why}; only a virtual camera {GUARD_FAR:.0e} depths of B back meets it"
        tried = psm_warp(view, light, body, options, x, frames)
        if tried.relative is None:
            return None, f"PSM's {why}; no single post-perspective frustum on the way back"
        axis, lam = map_lambda(tried.relative @ translation(-view.position), frames[0])
        guard = guard_lambda(0.0, at.gamma, axis, ctx)[0] if axis is not None else 0.0
        y = lam / guard if guard > 0.0 and math.isfinite(lam) else aim
        if abs(y - aim) <= GUARD_TOLERANCE / 2:
            return tried, f"virtual camera moved back to {x / warp.camera.near:.3g}x its near (§4.2): PSM's {why}"
        tried_points.append((x, y))
        low, high = (x, high) if y < aim else (low, x)
    return None, f"PSM's {why}; the search for its virtual camera did not converge"


def _pps_report(warp: PSMWarp) -> dict:
    camera, light_in_pps, l = warp.camera, warp.light_in_pps, warp.light_in_pps.light
    return {
        "pps_light": l,
        "pps_light_position": None if light_in_pps.kind == "directional" else l[:3] / l[3],     # L' as a PPS point
        "pps_light_kind": light_in_pps.kind,
        "virtual_shift": camera.shift,
        "virtual_near": camera.near,
        "virtual_far": camera.far,
        "visible_near": camera.visible_near,
        "pps_cone_half_angle_deg": math.degrees(light_in_pps.cone_half_angle),
    }


def _uniform_fallback(view: View, light: Light, body: IntersectionBody, options: WarpOptions,
                      diag: Diagnostics, what: str, reason: str) -> ShadowSetup:
    diag.fallback(what, reason)
    diag.extra["psm_applied"] = False
    return uniform_setup(view, light, body, options, diag)
