"""PSM on a point light behind the camera (Stamminger & Drettakis §3.2, Fig. 5: an inverted light in post-perspective
space) is no coarser than the uniform map: the map's x, y, square in post-perspective space, are skewed in the light's
image, and ``psm.turned_fit`` turns them back as far as that shortens the texel's longer side (§1.1's d_s, the side
that aliases), not as far as it shrinks its area (docs/papers.md, "pointpsm, session 24")."""
import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from addon.measure.footprint import setup_texel_footprint
from addon.warp import Light, SceneBounds, View, WarpOptions, compute, focused_body
from addon.warp.aliasing import raster_jacobian
from addon.warp.frame import light_frames
from addon.warp.methods.warp_frustum import map_lambda
from addon.warp.visibility import TileDepths, VisibleRegion


def point_behind_the_camera():
    """gen96_04_point_behind_camera as the render engine gave it to the warp core for PSM at 512²
    (``gen96_04_point_behind_camera.json``): B over the pre-pass's tiles, with the first look's edge samples."""
    d = json.loads(Path(__file__).with_name("gen96_04_point_behind_camera.json").read_text())
    t = d["tiles"]
    near, far = (np.array([[v if x is None else x for x in row] for row in t[k]], dtype=float)
                 for k, v in (("near", np.inf), ("far", -np.inf)))
    tiles = TileDepths(np.array(t["x_edges"]), np.array(t["y_edges"]), near, far, np.array(t["samples"]))
    view = View(np.array(d["camera_to_world"]), np.array(d["projection"]), d["near"], d["far"], tuple(d["resolution"]))
    light = Light("POINT", position=np.array(d["light_position"]), name="Lamp")
    scene = SceneBounds(np.array(d["casters"]), np.array(d["receivers"]), solid=False)
    options = WarpOptions(shadow_map_size=(512, 512), linear_z=True)
    body = focused_body(view, light, scene, options, VisibleRegion(tiles, "depth pre-pass"))
    points, directions, normals = np.moveaxis(np.array(d["edge_samples"]), 1, 0)
    body = dataclasses.replace(body, visible=dataclasses.replace(
        body.visible, surface=np.stack([points, points], 1), normals=normals, edge_directions=directions))
    return view, light, scene, options, body, np.array(d["lit_points"]), np.array(d["lit_normals"])


def test_psm_on_a_point_light_behind_the_camera_is_no_coarser_than_uniform():
    """The rendered-shadows issue's "never much worse than uniform", read on the texels. PSM's λ along its own axis
    is 20.6, far above the λ guard's 3.5, so the guard rightly leaves it; but its texels at B's centroid were
    parallelograms whose sides lie 54° apart in the light's image (0.66 by 0.34 of the light's image units per 512
    texels, uniform's 0.50 by 0.47), smaller in area than uniform's (0.94x) and longer (1.32x): turned by area, the
    turn did not act, and the p95 footprint over the lit points was 1.15x uniform's (2.19 against 1.91 px/texel;
    rendered 1.08x uniform's wrong pixels over 8 grid phases)."""
    view, light, scene, options, body, points, normals = point_behind_the_camera()
    setups = {m: compute(m, view, light, scene, options, body=body) for m in ("uniform", "psm")}
    assert [w for w, _ in setups["psm"].diagnostics.fallbacks] == []         # PSM serves, unguarded, as it did
    axis, lam = map_lambda(setups["psm"].maps[0].matrix, light_frames(view, light, body, options)[0])
    assert lam > 10.0
    p95 = {m: float(np.percentile(setup_texel_footprint(view, s, points, normals), 95)) for m, s in setups.items()}
    assert p95["psm"] <= p95["uniform"]


def test_psm_texel_axes_on_a_point_light_behind_the_camera_are_not_skewed_in_the_lights_image():
    """§1.1 prices a shadow-map texel as a square d_s x d_s on the light's image plane. PSM's texel at B's centroid
    (the fit's, before the turn off the shadow edges) has its sides at least 80° apart there, as the uniform map's
    are 90° (they were 54° apart)."""
    view, light, scene, options, body, _, _ = point_behind_the_camera()
    body = dataclasses.replace(body, visible=dataclasses.replace(body.visible, normals=None, edge_directions=None))
    frame = light_frames(view, light, body, options)[0]
    matrix = compute("psm", view, light, scene, options, body=body).maps[0].matrix
    centroid = frame.to_light @ np.append(body.volume_centroid, 1.0)
    j = raster_jacobian(matrix @ np.linalg.inv(frame.to_light), (2, 2), centroid[None, :3] / centroid[3])[0, :, :2]
    x, y = np.linalg.inv(j).T                                  # the texel's sides in the light's image
    assert math.degrees(math.acos(abs(x @ y) / math.hypot(*x) / math.hypot(*y))) >= 80.0
