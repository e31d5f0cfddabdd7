"""PSM's texel axes against the shadow edges (docs/papers.md, "Texel axes off the shadow edges", session 21)."""
import dataclasses
import json
from pathlib import Path

import numpy as np

from addon.warp import Light, SceneBounds, View, WarpOptions, compute, focused_body
from addon.warp.aliasing import raster_jacobian
from addon.warp.visibility import TileDepths, VisibleRegion


def low_sun_with_lit_points():
    """gen46_08_low_sun as the render engine gave it to the warp core (``gen46_08_low_sun.json``, the PSM footprint
    tests'), with its lit points and their normals."""
    d = json.loads(Path(__file__).with_name("gen46_08_low_sun.json").read_text())
    t = d["tiles"]
    near, far = (np.nan_to_num(np.array(t[k], dtype=float), nan=v) for k, v in (("near", np.inf), ("far", -np.inf)))
    visible = VisibleRegion(TileDepths(np.array(t["x_edges"]), np.array(t["y_edges"]), near, far), "depth pre-pass")
    view = View(np.array(d["camera_to_world"]), np.array(d["projection"]), d["near"], d["far"], tuple(d["resolution"]))
    light, boxes = Light("SUN", direction=np.array(d["sun_direction"]), name="Sun"), np.array(d["boxes"])
    scene, options = SceneBounds(boxes, boxes, solid=False), WarpOptions(shadow_map_size=(512, 512))
    body = focused_body(view, light, scene, options, visible)
    return view, light, scene, options, body, np.array(d["lit_points"]), np.array(d["lit_normals"])


def grid_angles(matrix, points, directions) -> np.ndarray:
    """Degrees from the image of each world direction at its point to the map's nearest texel axis (0..45)."""
    v = np.abs(np.einsum("nij,nj->ni", raster_jacobian(matrix, (2, 2), points), directions))
    return np.degrees(np.arctan2(v.min(axis=1), v.max(axis=1)))


def test_psm_turns_its_texel_axes_off_the_shadow_edges_it_is_given():
    """A straight shadow edge along a texel axis is stored as one long run: the map holds nothing of where the edge
    lies within a texel, and whole runs of pixels along it go wrong together (gen79_00_side_sun: PSM 1.22x uniform's
    wrong pixels over 8 grid phases, its edges 15.5° off its axes against uniform's 25.3°). Post-perspective space
    sets PSM's axes without the edges; given the first look's edge samples (here: lying along its x axis on the lit
    receivers), PSM turns its map about the depth axis so that they lie 20-45° off both axes, B still inside."""
    view, light, scene, options, body, points, normals = low_sun_with_lit_points()
    plain = compute("psm", view, light, scene, options, body=body).maps[0].matrix
    j = raster_jacobian(plain, (2, 2), points)                                   # (N, 2, 3)
    d = np.linalg.solve(np.stack([j[:, 0], j[:, 1], normals], 1), np.tile([1.0, 0.0, 0.0], (len(points), 1)))
    d /= np.linalg.norm(d, axis=1)[:, None]                                      # D_M·d = (·, 0), n·d = 0
    assert np.median(grid_angles(plain, points, d)) < 0.01
    looked = dataclasses.replace(body, visible=dataclasses.replace(
        body.visible, surface=np.stack([points, points], 1), normals=normals, edge_directions=d))
    setup = compute("psm", view, light, scene, options, body=looked)
    assert setup.diagnostics.extra["psm_applied"] and setup.maps[0].contains(body.vertices, 1e-6).all()
    assert np.percentile(grid_angles(setup.maps[0].matrix, points, d), 10) >= 20.0
