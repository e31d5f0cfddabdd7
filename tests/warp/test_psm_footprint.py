"""PSM against the uniform map on the example configs: texel footprint (screen
pixels per texel, ``measure.footprint.texel_footprint``) at the visible surface points,
float32 upload error and orientation (winding) of the map."""
import json
import math
from pathlib import Path

import numpy as np
import pytest

from addon.warp import Light, SceneBounds, View, WarpOptions, compute, focused_body, intersection_body
from addon.warp.frame import light_frames
from addon.warp.geometry import translation
from addon.warp.methods.psm import psm_warp
from addon.warp.visibility import TileDepths, VisibleRegion
from addon.measure.footprint import setup_texel_footprint
from addon.cli.config import parse_config

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
NAMES = ["outdoor_sun", "sun_behind_camera", "sun_overhead", "chess_spot", "terrain_point"]


def visible_surface(view, scene, grid=(96, 54)):
    """Nearest box hit (point, outward normal) through a grid of pixel centres."""
    gx, gy = grid
    x = (np.arange(gx) + 0.5) / gx * 2 - 1
    y = (np.arange(gy) + 0.5) / gy * 2 - 1
    xx, yy = np.meshgrid(x, y)
    inv = np.linalg.inv(view.world_to_clip)
    def unproject(z):
        h = np.column_stack([xx.ravel(), yy.ravel(), np.full(xx.size, z), np.ones(xx.size)]) @ inv.T
        return h[:, :3] / h[:, 3:4]
    a, b = unproject(-1.0), unproject(1.0)
    d = b - a
    best = np.full(len(a), np.inf)
    normal = np.zeros_like(a)
    with np.errstate(divide="ignore", invalid="ignore"):
        for lo, hi in scene.receivers:
            t0, t1 = (lo - a) / d, (hi - a) / d
            tmin, tmax = np.minimum(t0, t1), np.maximum(t0, t1)
            enter = np.nanmax(tmin, axis=1)
            leave = np.nanmin(tmax, axis=1)
            hit = (enter <= leave) & (enter >= 0) & (enter <= 1) & (enter < best)
            axis = np.nanargmax(tmin, axis=1)
            best[hit] = enter[hit]
            n = np.zeros_like(a)
            n[np.arange(len(a)), axis] = -np.sign(d[np.arange(len(a)), axis])
            normal[hit] = n[hit]
    ok = np.isfinite(best)
    return a[ok] + best[ok, None] * d[ok], normal[ok]


def lit_surface(view, light, scene):
    """Visible surface points, without those outside a spot's cone (unlit, not in B)."""
    pts, nrm = visible_surface(view, scene)
    if light.type == "SPOT":
        d = pts - light.position
        keep = (d / np.linalg.norm(d, axis=1, keepdims=True)) @ light.direction >= math.cos(light.spot_angle / 2)
        pts, nrm = pts[keep], nrm[keep]
    return pts, nrm


def load(name):
    view, light, scene, options = parse_config(json.loads((EXAMPLES / f"{name}.json").read_text()))
    return view, light, scene, options, intersection_body(view, light, scene)


def footprint_stats(name):
    view, light, scene, options, body = load(name)
    pts, nrm = lit_surface(view, light, scene)
    out = {}
    for method in ("uniform", "psm"):
        setup = compute(method, view, light, scene, options, body=body)
        f = setup_texel_footprint(view, setup, pts, nrm)
        assert not np.isnan(f).any(), f"{method}: a visible point is not served by any map"
        fin = f[np.isfinite(f)]
        out[method] = (float(np.percentile(fin, 95)), float(fin.max()), setup)
    return out


def test_psm_beats_uniform_where_the_paper_says_it_should():
    """§3.3: the gain is largest for a sun across the view (outdoor_sun,
    sun_behind_camera), and PSM degrades towards the uniform map as the light
    aligns with the view (sun_overhead is 81° from a view that looks almost
    horizontally, so it still gains). p95 and max screen pixels per texel."""
    for name in ("outdoor_sun", "sun_behind_camera", "sun_overhead"):
        s = footprint_stats(name)
        (up95, umax, _), (pp95, pmax, _) = s["uniform"], s["psm"]
        assert pp95 < 0.5 * up95, (name, up95, pp95)
        assert pmax < umax, (name, umax, pmax)


@pytest.mark.parametrize("name", NAMES)
def test_psm_footprint_is_finite_on_every_example(name):
    s = footprint_stats(name)
    pp95, pmax, setup = s["psm"]
    assert math.isfinite(pp95) and pp95 > 0
    # terrain_point: a lamp 40 m over a 1 km terrain needs a ~176° PPS frustum -> uniform cube faces
    assert setup.diagnostics.extra["psm_applied"] == (name != "terrain_point")
    if name == "terrain_point":
        assert setup.diagnostics.fallbacks[0][0] == "PPS light frustum"
        assert pp95 == pytest.approx(s["uniform"][0])


def test_spot_over_the_chess_board_gains_over_uniform():
    s = footprint_stats("chess_spot")
    assert s["psm"][0] < 0.8 * s["uniform"][0] and s["psm"][1] < s["uniform"][1]


def _ndc(matrix, points, dtype):
    m = matrix.astype(dtype)
    h = np.hstack([points, np.ones((len(points), 1))]).astype(dtype) @ m.T
    return (h[:, :3] / h[:, 3:4]).astype(np.float64)


@pytest.mark.parametrize("name", NAMES)
def test_float32_upload_error_is_far_below_a_texel(name):
    view, light, scene, options, body = load(name)
    setup = compute("psm", view, light, scene, options, body=body)
    m = setup.maps[0]
    err = np.abs(_ndc(m.matrix, body.vertices, np.float32) - _ndc(m.matrix, body.vertices, np.float64))
    assert (err[:, :2] * np.asarray(m.size) / 2).max() < 0.05


def orientation(matrix, points):
    """Sign of det d(NDC)/d(world) at points (the map's handedness)."""
    h = np.hstack([points, np.ones((len(points), 1))]) @ matrix.T
    ndc = h[:, :3] / h[:, 3:4]
    jac = (matrix[None, :3, :3] - ndc[:, :, None] * matrix[None, 3:4, :3]) / h[:, 3, None, None]
    return np.sign(np.linalg.det(jac))


@pytest.mark.parametrize("name", NAMES)
def test_psm_keeps_the_uniform_maps_handedness(name):
    """Triangles facing the light keep their winding, as in the uniform map
    (back-face biasing renders by winding)."""
    view, light, scene, options, body = load(name)
    u = compute("uniform", view, light, scene, options, body=body).maps[0].matrix
    p = compute("psm", view, light, scene, options, body=body).maps[0].matrix
    su, sp = orientation(u, body.vertices), orientation(p, body.vertices)
    assert np.all(su == su[0]) and np.all(sp == su[0])


# ----------------------------------------------------------------------------- a low sun behind the camera

def low_sun_behind_the_camera():
    """gen46_08_low_sun as the render engine gave it to the warp core (``gen46_08_low_sun.json``): the sun 16.7° from
    the view direction and 7° up, behind the camera; B from the depth pre-pass's tiles."""
    d = json.loads(Path(__file__).with_name("gen46_08_low_sun.json").read_text())
    t = d["tiles"]
    near, far = (np.array(t[k], dtype=float) for k in ("near", "far"))      # null: the tile sees nothing
    visible = VisibleRegion(TileDepths(np.array(t["x_edges"]), np.array(t["y_edges"]), np.nan_to_num(near, nan=np.inf),
                                       np.nan_to_num(far, nan=-np.inf)), "depth pre-pass")
    view = View(np.array(d["camera_to_world"]), np.array(d["projection"]), d["near"], d["far"], tuple(d["resolution"]))
    light, boxes = Light("SUN", direction=np.array(d["sun_direction"]), name="Sun"), np.array(d["boxes"])
    scene, options = SceneBounds(boxes, boxes, solid=False), WarpOptions(shadow_map_size=(512, 512))
    return view, light, scene, options, focused_body(view, light, scene, options, visible)


def texel_area_in_the_lights_image(matrix, frame, point, step=1e-4):
    """The area of a texel of the map ``matrix`` (world -> clip) on the light frame's image plane at ``point``, by
    central differences along the frame's x and y (its texel's area: 1)."""
    along = np.linalg.inv(frame.to_light)[:3, :2].T * step                 # world steps of ``step`` along its x, y
    def ndc(p):
        h = matrix @ np.append(p, 1.0)
        return h[:2] / h[3]
    jacobian = np.column_stack([(ndc(point + a) - ndc(point - a)) / (2 * step) for a in along])
    return 1.0 / abs(np.linalg.det(jacobian))


def test_as_the_virtual_camera_moves_back_psm_tends_to_the_uniform_maps_texel():
    """§4.2: with the virtual camera at infinity, PSM is the uniform map. Under a low sun behind the camera, x and y
    square in post-perspective space are skewed in the light's image; turned towards the light's, PSM's texel at B's
    centroid tends to the uniform map's as the camera moves back (unturned it stayed 2.6 times its area)."""
    view, light, scene, options, body = low_sun_behind_the_camera()
    frames = light_frames(view, light, body, options)
    centroid = body.volume_centroid
    uniform = texel_area_in_the_lights_image(compute("uniform", view, light, scene, options, body=body).maps[0].matrix,
                                             frames[0], centroid)
    ratios = [texel_area_in_the_lights_image(psm_warp(view, light, body, options, near, frames).relative
                                             @ translation(-view.position), frames[0], centroid) / uniform
              for near in (1e2, 1e4, 1e6)]
    assert ratios[-1] == pytest.approx(1.0, abs=0.01)
    assert abs(ratios[0] - 1.0) >= abs(ratios[1] - 1.0) >= abs(ratios[2] - 1.0)


def test_under_a_low_sun_behind_the_camera_psm_is_no_coarser_than_uniform():
    """The rendered-shadows issue's "never much worse than uniform", read on the texels: under a low sun behind the
    camera, PSM's p95 footprint over the lit points facing the light is no larger than the uniform map's (with x, y
    square in post-perspective space it was 1.7 times it, λ guard or not: the guard reads only PSM's λ)."""
    view, light, scene, options, body = low_sun_behind_the_camera()
    d = json.loads(Path(__file__).with_name("gen46_08_low_sun.json").read_text())
    pts, nrm = np.array(d["lit_points"]), np.array(d["lit_normals"])
    p95 = {m: float(np.percentile(setup_texel_footprint(view, compute(m, view, light, scene, options, body=body),
                                                        pts, nrm), 95)) for m in ("uniform", "psm")}
    assert p95["psm"] <= p95["uniform"]
