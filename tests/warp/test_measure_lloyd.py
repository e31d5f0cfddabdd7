"""Lloyd's N_min against its two closed forms, and its invariances."""
import math

import numpy as np
import pytest

from addon.measure import lloyd
from addon.warp.geometry import look_along
from addon.warp.types import Light, View


def _view(forward, up, fov_y_deg, aspect, near, far, res=(640, 480)):
    c2w = np.linalg.inv(look_along([1.0, -2.0, 0.5], forward, up))
    return View.perspective(c2w, math.radians(fov_y_deg), aspect, near, far, res)


CASES = [(60, 1.0, 0.1, 70.0), (60, 16 / 9, 1.0, 800.0), (25, 2.0, 0.5, 300.0), (90, 0.75, 0.01, 1.0)]


@pytest.mark.parametrize("fov,aspect,near,far", CASES)
def test_light_perpendicular_to_view_matches_closed_form(fov, aspect, near, far):
    # camera looks along +Y with +Z up; the sun travels along -Z: perpendicular, in the
    # camera's vertical plane, so theta is the vertical half field of view.
    v = _view([0, 1, 0], [0, 0, 1], fov, aspect, near, far)
    got = lloyd.n_min(v, Light("SUN", direction=[0, 0, -1]))
    want = lloyd.n_min_perpendicular(v.resolution, math.tan(v.fov_y / 2), near, far)
    assert got == pytest.approx(want, rel=1e-3)


@pytest.mark.parametrize("fov,aspect,near,far", CASES)
def test_light_perpendicular_in_horizontal_plane_uses_horizontal_half_angle(fov, aspect, near, far):
    v = _view([0, 1, 0], [0, 0, 1], fov, aspect, near, far)
    got = lloyd.n_min(v, Light("SUN", direction=[1, 0, 0]))
    want = lloyd.n_min_perpendicular(v.resolution, math.tan(v.fov_x / 2), near, far)
    assert got == pytest.approx(want, rel=1e-3)


@pytest.mark.parametrize("fov,aspect,near,far", CASES)
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_light_parallel_to_view_matches_closed_form(fov, aspect, near, far, sign):
    v = _view([0, 1, 0], [0, 0, 1], fov, aspect, near, far)
    got = lloyd.n_min(v, Light("SUN", direction=[0, sign, 0]))
    assert got == pytest.approx(lloyd.n_min_parallel(v.resolution, near, far), rel=1e-3)


def test_limit_grows_from_perpendicular_to_parallel_and_is_symmetric():
    v = _view([0, 1, 0], [0, 0, 1], 60, 1.0, 0.1, 70.0)
    vals = []
    for deg in (0, 30, 60, 89):
        a = math.radians(deg)
        vals.append(lloyd.n_min(v, Light("SUN", direction=[0, math.sin(a), -math.cos(a)])))
        mirrored = lloyd.n_min(v, Light("SUN", direction=[0, -math.sin(a), math.cos(a)]))
        assert mirrored == pytest.approx(vals[-1], rel=1e-9)
    assert vals == sorted(vals)
    assert vals[-1] < lloyd.n_min_parallel(v.resolution, 0.1, 70.0)


def test_distant_point_light_approaches_the_sun():
    v = _view([0, 1, 0], [0, 0, 1], 60, 4 / 3, 0.1, 70.0)
    sun = lloyd.n_min(v, Light("SUN", direction=[0, 0, -1]))
    far_point = lloyd.n_min(v, Light("POINT", position=[1.0, 30.0, 1e6]))
    assert far_point == pytest.approx(sun, rel=2e-3)


def test_point_light_inside_the_frustum_is_refused():
    v = _view([0, 1, 0], [0, 0, 1], 60, 1.0, 0.1, 70.0)
    with pytest.raises(ValueError, match="inside or beside"):
        lloyd.n_min(v, Light("POINT", position=[1.0, 10.0, 0.5]))


def test_m_min_scales_with_the_budget():
    assert lloyd.m_min(4e6, 1e6) == pytest.approx(2.0)
    assert lloyd.m_min(1e6, 4e6) == pytest.approx(0.5)
    with pytest.raises(ValueError):
        lloyd.m_min(1.0, 0)


def test_inverse_square_integral_matches_brute_force():
    rng = np.random.default_rng(3)
    tri = rng.uniform(-1, 1, (3, 2))
    vals = np.array([0.3, 2.0, 0.31])
    got = float(lloyd.integral_inverse_square_affine(tri[None], vals[None])[0])
    # Monte Carlo-free check: fine barycentric grid (midpoint rule on a subdivided triangle)
    sub = lloyd._subdivide(np.concatenate([tri, vals[:, None]], axis=1)[None], 7)
    centre = sub.mean(axis=1)
    e1, e2 = sub[:, 1, :2] - sub[:, 0, :2], sub[:, 2, :2] - sub[:, 0, :2]
    area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    brute = float(np.sum(area / centre[:, 2] ** 2))
    assert got == pytest.approx(brute, rel=1e-3)
    # nearly constant values take the stable branch
    flat = float(lloyd.integral_inverse_square_affine(tri[None], np.array([[2.0, 2.0 + 1e-9, 2.0]]))[0])
    e1, e2 = tri[1] - tri[0], tri[2] - tri[0]
    assert flat == pytest.approx(0.5 * abs(e1[0] * e2[1] - e1[1] * e2[0]) / 4.0, rel=1e-7)
