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
import pytest

from addon.warp import WarpOptions
from addon.warp.aliasing import raster_jacobian
from addon.warp.methods.cascade import cascade
from addon.warp.methods.warp_frustum import TURNS
from addon.warp.partition.receivers import spun
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


def test_a_point_lights_far_split_turns_its_texel_axes_off_the_shadow_edges_laid_along_them():
    """Edges given on the far split's ground along its map's x axis: the pick keeps its map (or a layout of it) no
    more, but one turned so that the edges lie out of the band within 8° of a texel axis, where a grid along an edge
    loses PCF's whole gain (``filter_losses``); the split keeps a single map."""
    view, light, scene, options, region, body, far = street_lamp()
    ground = (region.normals[:, 2] > 0.9) & far.serves(region.surface[:, 0], view)
    p, n = region.surface[ground, 0], region.normals[ground]
    j = raster_jacobian(far.matrix, (2, 2), p)
    d = np.linalg.solve(np.stack([j[:, 0], j[:, 1], n], 1), np.tile([1.0, 0.0, 0.0], (len(p), 1)))
    d /= np.linalg.norm(d, axis=1)[:, None]                                      # D_M·d = (·, 0), n·d = 0
    assert far.role == "split3:main" and len(p) >= 100 and grid_angles(far.matrix, p, d).max() < 1e-6
    edges = np.zeros_like(region.normals)
    edges[ground] = d
    looked = dataclasses.replace(body, visible=dataclasses.replace(region, source="depth pre-pass",
                                                                   edge_directions=edges))
    turned = cascade(view, light, looked, options, scene).maps[-1]
    assert turned.role == "split3:main" and turned.serves(p, view).all()
    assert grid_angles(turned.matrix, p, d).min() >= 8.0


@pytest.mark.parametrize("lamp", [[0.0, -16.0, 1.5], [2.5, -16.0, 0.7]])
def test_each_turn_of_a_map_whose_light_is_a_vertex_of_b_holds_b_in_front_of_the_light(lamp):
    """The turns are fitted to B clipped to the map's own near plane (B's vertex at the light has w = 0): each holds
    every point of B the map held, and its depth row is the map's to rounding (only x, y turn)."""
    view, _, scene = HARD_CASES["sun_behind_camera"]
    light, region, options = point(lamp), region_from_boxes(view, scene), WarpOptions(shadow_map_size=(1024, 1024))
    setup = cascade(view, light, focused_body(view, light, scene, options, region), options, scene)
    far, body = setup.maps[-1], setup.diagnostics.extra["split_bodies"][-1]
    held = body[far.contains(body, 1e-6)]
    assert len(held) < len(body)                                         # (the light itself: w = 0)
    turns = spun(far.matrix, body, TURNS)
    assert len(turns) == 36
    for m in turns:
        h = held @ m[:3, :3].T + m[:3, 3]
        w = held @ m[3, :3] + m[3, 3]
        assert (w > 0).all() and (np.abs(h / w[:, None]) <= 1.0 + 1e-6).all()
        assert np.allclose(m[2:], far.matrix[2:], rtol=1e-6, atol=1e-9 * np.abs(far.matrix[2:]).max())

