"""Uniform (focused standard) shadow maps: the light frustum fitted to B.

Scherzer §4.1 (focusing on the intersection body B); Brabec et al. via
Scherzer [4]. For a sun the map is orthographic; for point and spot lights it
is the light's perspective, one map per needed cube face when B does not fit a
single frustum (see ``frame.point_frames``).

Texel snapping (option, suns): the map is built in a light frame fixed in the
world (``frame.world_sun_frame``), its window size is quantised to a ladder of
sizes (8 per octave) and its origin to whole texels, so while the camera moves
every world point keeps its texel (an integer shift of the whole map) and
shadow edges do not crawl; the window changes size only when B's extent
crosses a ladder step.
"""
from __future__ import annotations

import math

import numpy as np

from ..body import IntersectionBody
from ..fit import fit_runs, ndc_bounds, ndc_box, window_matrix
from ..frame import LightFrame, body_light_angles, light_frames, world_sun_frame
from ..geometry import point_runs
from ..types import Diagnostics, Light, ShadowMap, ShadowSetup, View, WarpOptions

SNAP_STEPS_PER_OCTAVE = 8


def map_sizes(options: WarpOptions, count: int) -> tuple[int, int]:
    """Each of ``count`` maps gets the full per-map size (the budget is per map)."""
    return options.shadow_map_size


def snapped_window(lo: np.ndarray, hi: np.ndarray, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Grow the x/y window [lo, hi] to a quantised extent whose origin sits on
    whole texels (orthographic frames only: light-space units are world units)."""
    lo, hi = lo.copy(), hi.copy()
    for axis in (0, 1):
        ext = max(hi[axis] - lo[axis], 1e-300)
        ladder = 2.0 ** (math.ceil(math.log2(ext) * SNAP_STEPS_PER_OCTAVE) / SNAP_STEPS_PER_OCTAVE)
        texel = ladder / size[axis]
        start = math.floor(lo[axis] / texel) * texel
        end = start + ladder
        if end < hi[axis]:
            end += texel * math.ceil((hi[axis] - end) / texel)
        lo[axis], hi[axis] = start, end
    return lo, hi


def frame_map(frame: LightFrame, options: WarpOptions, snap: bool = False) -> ShadowMap:
    """An unwarped map for one light frame, fitted to the frame's points."""
    if snap and frame.directional:
        lo, hi = ndc_bounds(frame.to_light, frame.points)
        lo, hi = snapped_window(lo, hi, options.shadow_map_size)
        matrix = window_matrix(lo, hi) @ frame.to_light
    else:
        matrix = window_matrix(*ndc_box(frame.points_h @ frame.to_light.T)) @ frame.to_light
    return ShadowMap(matrix, options.shadow_map_size, "LESS", frame.role)


def uniform_maps(view: View, light: Light, body: IntersectionBody,
                 options: WarpOptions) -> tuple[list[ShadowMap], list[LightFrame]]:
    """The uniform maps and the light frames they are fitted in (without the
    diagnostics: PSM hands over to these maps and reports on its own)."""
    if options.texel_snapping and light.is_directional:
        frames = [world_sun_frame(light, body)]      # a texel grid fixed in the world
    else:
        frames = light_frames(view, light, body, options)
    if len(frames) > 1:                              # a point light's cube faces: fitted all at once
        to_light = np.array([f.to_light for f in frames])
        fitted = fit_runs(to_light, *point_runs([f.points for f in frames]))
        return [ShadowMap(m, options.shadow_map_size, "LESS", f.role) for m, f in zip(fitted, frames)], frames
    return [frame_map(frames[0], options, options.texel_snapping)], frames


def near_plane_notes(frames: list[LightFrame]) -> list[tuple[str, str]]:
    """The fallbacks to record for frames whose near plane was clamped (the light inside B)."""
    return [(f"{f.role}: near plane", "the light is inside B; points nearer than 1e-6 of the scene scale are not covered")
            for f in frames if f.near_clamped]


def uniform(view: View, light: Light, body: IntersectionBody, options: WarpOptions) -> ShadowSetup:
    maps, frames = uniform_maps(view, light, body, options)
    diag = Diagnostics("uniform", body_vertices=body.vertices)
    diag.report_angles(lambda: body_light_angles(view, light, body))
    diag.fallbacks.extend(near_plane_notes(frames))
    diag.extra["frames"] = [f.role for f in frames]
    return ShadowSetup(maps, diag)
