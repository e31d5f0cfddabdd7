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
from ..frame import body_light_angles
from ..types import Light, ShadowSetup, View, WarpOptions
from .common import near_plane_notes, uniform_maps


def uniform(view: View, light: Light, body: IntersectionBody, options: WarpOptions) -> ShadowSetup:
    maps, frames = uniform_maps(view, light, body, options)
    theta, gamma = body_light_angles(view, light, body)
    diag = Diagnostics("uniform", theta, gamma, body_vertices=body.vertices, fallbacks=near_plane_notes(frames))
    diag.extra["frames"] = [f.role for f in frames]
    return ShadowSetup(maps, diag)
