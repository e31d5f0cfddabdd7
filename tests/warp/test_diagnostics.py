"""A warped frame reports its warp frustum's corners, its projection centre and
B's middle vector, as JSON without NaN."""
import json
import math

import numpy as np
import pytest

from addon.warp import Light, SceneBounds, View, WarpOptions, compute, intersection_body
from addon.warp.geometry import UNIT_CUBE_CORNERS, clip_volume_corners, clip_volume_corners_h, look_along
from addon.cli.output import setup_json

SCENE = SceneBounds.from_boxes([[[-50.0, -50.0, -0.1], [50.0, 50.0, 0.0]]]
                               + [[[x, y, 0.0], [x + 1.0, y + 1.0, 3.0]] for x in (-12.0, 0.0, 12.0) for y in (5.0, 20.0)])


def _view():
    c2w = np.linalg.inv(look_along(np.array([0.0, -10.0, 2.0]), np.array([0.0, 1.0, -0.2]), np.array([0.0, 0.0, 1.0])))
    return View.perspective(c2w, math.radians(60.0), 16 / 9, 0.1, 70.0, (1280, 720))


LIGHTS = [Light("SUN", direction=[0.3, 0.5, -0.8]), Light("POINT", position=[4.0, 10.0, 8.0])]


@pytest.mark.parametrize("light", LIGHTS, ids=["sun", "point"])
@pytest.mark.parametrize("method", ["lispsm", "gmnpr", "glpr"])
def test_a_warped_frame_reports_its_frustum_centre_and_middle_vector(light, method):
    view = _view()
    body = intersection_body(view, light, SCENE)
    setup = compute(method, view, light, SCENE, WarpOptions(), body=body)
    diag = setup.diagnostics
    # the corners of the first warped map's clip volume
    assert any(np.allclose(diag.warp_frustum_corners, clip_volume_corners(m.matrix)) for m in setup.maps)
    middle = body.volume_centroid - view.position
    assert np.allclose(diag.extra["middle_vector"], middle / np.linalg.norm(middle))
    assert diag.extra["projection_centre"] is None or np.all(np.isfinite(diag.extra["projection_centre"]))
    json.dumps(setup_json(setup), allow_nan=False)


def test_the_middle_vector_option_still_steers_the_warp():
    view, light = _view(), LIGHTS[0]
    body = intersection_body(view, light, SCENE)
    plain = compute("lispsm", view, light, SCENE, WarpOptions(), body=body)
    middle = compute("lispsm", view, light, SCENE, WarpOptions(middle_vector=True), body=body)
    assert not np.allclose(plain.maps[0].matrix, middle.maps[0].matrix)


@pytest.mark.parametrize("method", ["lispsm", "gmnpr", "glpr"])
def test_a_warp_frustum_through_infinity_reports_no_mirrored_corners(method):
    """Where P passes through infinity (a clip corner at w < 0), dividing by w gives finite corners on the wrong
    side: no corners are reported then (as PSM does), and reported corners are P's, each in front (w > 0)."""
    from hard_cases import HARD_CASES
    view, light, scene = HARD_CASES["point_light_in_camera_plane"]
    setup = compute(method, view, light, scene, WarpOptions(shadow_map_size=1024))
    assert len(setup.maps) == 1 and np.any(clip_volume_corners_h(setup.maps[0].matrix)[:, 3] < 0)   # P's map
    assert setup.diagnostics.warp_frustum_corners is None
    setup = compute(method, _view(), LIGHTS[1], SCENE, WarpOptions())
    h = [np.c_[setup.diagnostics.warp_frustum_corners, np.ones(8)] @ m.matrix.T for m in setup.maps]
    assert any(np.all(p[:, 3] > 0) and np.allclose(p[:, :3] / p[:, 3:], UNIT_CUBE_CORNERS) for p in h)
