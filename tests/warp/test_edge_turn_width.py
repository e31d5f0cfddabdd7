"""The one-map turn off the shadow edges (``warp_frustum.edge_turned``, PSM's and the LiSPSM family's) weighs each
turn by ``partition.receivers.filter_losses`` alone: its texels' width across the first look's shadow edges and the
edges' share near a texel axis, the two things the rendered error follows there (docs/papers.md, "family, session
23")."""
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from addon.warp import Light, SceneBounds, View, WarpOptions, compute, focused_body
from addon.warp.partition.receivers import filter_losses
from addon.warp.types import ShadowSetup
from addon.warp.visibility import TileDepths, VisibleRegion

from test_psm_edge_axes import grid_angles


def low_sun_with_edges():
    """gen48_02_low_sun as the render engine gave it to the warp core for LiSPSM at 2048² (``gen48_02_low_sun_edges
    .json``): B over the pre-pass's tiles, and B with the first look's edge samples (point, direction, normal)."""
    d = json.loads(Path(__file__).with_name("gen48_02_low_sun_edges.json").read_text())
    t = d["tiles"]
    near, far = (np.array([[v if x is None else x for x in row] for row in t[k]], dtype=float)
                 for k, v in (("near", np.inf), ("far", -np.inf)))
    tiles = TileDepths(np.array(t["x_edges"]), np.array(t["y_edges"]), near, far, np.array(t["samples"]),
                       np.array(t["edges"]))
    view = View(np.array(d["camera_to_world"]), np.array(d["projection"]), d["near"], d["far"], tuple(d["resolution"]))
    light = Light("SUN", direction=np.array(d["sun_direction"]), name="Sun")
    scene = SceneBounds(np.array(d["casters"]), np.array(d["receivers"]), solid=False)
    options = WarpOptions(shadow_map_size=(2048, 2048))
    body = focused_body(view, light, scene, options, VisibleRegion(tiles, "depth pre-pass"))
    points, directions, normals = np.moveaxis(np.array(d["edge_samples"]), 1, 0)
    looked = dataclasses.replace(body, visible=dataclasses.replace(
        body.visible, surface=np.stack([points, points], 1), normals=normals, edge_directions=directions))
    return view, light, scene, options, body, looked, np.array(d["edge_samples"])


@pytest.mark.parametrize("method", ["lispsm", "gmnpr", "glpr"])
def test_the_edge_turn_does_not_lay_the_edges_along_the_grid_for_a_smaller_texel_elsewhere(method):
    """gen48_02_low_sun, 2048²: LiSPSM's map turned 40° is 0.69x as wide across the edges and its texel at B's centre
    0.69x as long, but it lays half the edges within 8-20° of a texel axis. Weighed by that texel's side as well as by
    ``filter_losses`` (which weighs the width already), it was taken, and it rendered 1.29x the unturned map's wrong
    pixels over 8 grid phases (79.4 ± 8.8 against 61.6 ± 3.4; uniform 68.9), as ``filter_losses`` says (2.10
    against 1.61). The map each of the family takes loses no more at those edges than its unturned map, and lays them
    20° or more off its texel axes on average."""
    view, light, scene, options, body, looked, edges = low_sun_with_edges()
    unturned = compute(method, view, light, scene, options, body=body).maps[0]
    turned = compute(method, view, light, scene, options, body=looked).maps[0]
    assert turned.contains(body.vertices, 1e-6).all()
    loss = filter_losses([ShadowSetup([m], None) for m in (unturned, turned)], (None,) * 4 + (edges,))
    assert loss[1] <= loss[0]
    assert np.mean(grid_angles(turned.matrix, edges[:, 0], edges[:, 1])) >= 20.0
