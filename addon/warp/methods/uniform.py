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

from ..body import IntersectionBody
from ..diagnostics import Diagnostics
from ..frame import LightFrame, body_light_angles, light_frames, world_sun_frame
from ..types import Light, ShadowMap, ShadowSetup, View, WarpOptions
from .common import frame_maps, near_plane_notes


def uniform_maps(view: View, light: Light, body: IntersectionBody,
                 options: WarpOptions) -> tuple[list[ShadowMap], list[LightFrame]]:
    """The uniform maps and the light frames they are fitted in (PSM hands
    over to these maps and reports on its own)."""
    if options.texel_snapping and light.is_directional:
        frames = [world_sun_frame(light, body)]      # a texel grid fixed in the world
    else:
        frames = light_frames(view, light, body, options)
    return frame_maps(frames, options.shadow_map_size, options.texel_snapping, options.linear_z), frames


def uniform(view: View, light: Light, body: IntersectionBody, options: WarpOptions) -> ShadowSetup:
    maps, frames = uniform_maps(view, light, body, options)
    theta, gamma = body_light_angles(view, light, body)
    diag = Diagnostics("uniform", theta, gamma, body_vertices=body.vertices, fallbacks=near_plane_notes(frames))
    diag.extra["frames"] = [f.role for f in frames]
    return ShadowSetup(maps, diag)
