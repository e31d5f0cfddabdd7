"""A point light's cascade turns its single maps off the known shadow edges (docs/papers.md, "pturn, session 22").

The far split of a point light low in the view (gen84_11_point_low_in_view's kind) is one perspective map whose light
is a vertex of its B: no hull turn fits it (w = 0 there), so its pick had nothing to choose among but the map and its
2:1 layouts, and where the box edges' shadows ran along its texel axes it rendered 1.65x uniform's wrong pixels. Its
single maps are now also offered turned about their depth axis by ``TURNS``, refitted to their own window, and scored
by ``filter_losses`` as PSM's turn and the sun's candidates are.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from addon.warp import WarpOptions
from addon.warp.aliasing import raster_jacobian
from addon.warp.methods.cascade import cascade
from addon.warp.partition.receivers import filter_losses
from addon.warp.types import ShadowSetup
from addon.warp.visibility import focused_body, region_from_boxes
from hard_cases import HARD_CASES, point


def grid_angles(matrix, points, directions) -> np.ndarray:
    """Degrees from the image of each world direction at its point to the map's nearest texel axis (0..45)."""
    v = np.abs(np.einsum("nij,nj->ni", raster_jacobian(matrix, (2, 2), points), directions))
    return np.degrees(np.arctan2(v.min(axis=1), v.max(axis=1)))


def street_lamp():
    """sun_behind_camera's town under a lamp 1.5 m up, 4 m ahead of the camera: the far split is one map whose light
    is a vertex of its B; its receivers, as the engine's pre-pass gives them, and that split's options and maps."""
    view, _, scene = HARD_CASES["sun_behind_camera"]
    light, region = point([0.0, -16.0, 1.5]), region_from_boxes(view, scene)
    options = WarpOptions(shadow_map_size=(1024, 1024))
    body = focused_body(view, light, scene, options, region)
    return view, light, scene, options, region, body, cascade(view, light, body, options, scene).maps[-1]


def test_shadow_edges_behind_a_map_weigh_nothing_rather_than_unscore_it():
    """Edges behind a point light's map (w < 0: no image) leave its footprints as they are, as no edges do, for a
    single map and for several faces alike; a NaN weight made every footprint of the candidate NaN, so that the p95
    that scores the splits left its receivers out (cube splits of gen44_11_point_low_in_view)."""
    far = street_lamp()[-1]
    behind = np.array([[x, -30.0, 0.0] for x in np.linspace(-5.0, 5.0, 25)])            # the lamp is at y = -16
    edges = np.stack([behind, np.tile([1.0, 0.0, 0.0], (25, 1)), np.tile([0.0, 0.0, 1.0], (25, 1))], 1)
    assert filter_losses([ShadowSetup([far], None), ShadowSetup([far, far], None)],
                         (None,) * 4 + (edges,)).tolist() == [1.0, 1.0]
