"""A View is immutable, so what is derived from it (inverse, clip matrix,
corners, direction) is computed once: it must own its matrices, and nothing it
hands out may be edited in place."""
import math

import numpy as np
import pytest

from addon.warp import View
from addon.warp.geometry import look_along


def a_view() -> View:
    c2w = np.linalg.inv(look_along(np.array([1.0, -4.0, 2.0]), np.array([0.2, 1.0, -0.3]), [0.0, 0.0, 1.0]))
    return View.perspective(c2w, math.radians(50.0), 16 / 9, 0.1, 80.0)


def test_a_view_owns_its_matrices():
    m = a_view().camera_to_world.copy()
    original = m.copy()
    view = View(m, a_view().projection, 0.1, 80.0)
    before = view.corners().copy()
    m[0, 3] += 10.0                                  # the caller's array, edited afterwards
    assert np.array_equal(view.camera_to_world, original)
    assert np.array_equal(view.corners(), before)


@pytest.mark.parametrize("name", ["camera_to_world", "projection", "world_to_camera", "world_to_clip", "direction", "up"])
def test_what_a_view_hands_out_is_read_only(name):
    value = getattr(a_view(), name)
    with pytest.raises(ValueError):
        value[0] = 0.0


def test_derived_values_agree_with_their_definitions():
    view = a_view()
    assert np.allclose(view.world_to_camera @ view.camera_to_world, np.eye(4))
    assert np.allclose(view.world_to_clip, view.projection @ view.world_to_camera)
    h = np.c_[view.corners(), np.ones(8)] @ view.world_to_clip.T
    assert np.allclose(np.abs(h[:, :3] / h[:, 3:]), 1.0)
    assert view.corners() is view.corners()          # computed once
    with pytest.raises(ValueError):
        view.corners()[0, 0] = 0.0
