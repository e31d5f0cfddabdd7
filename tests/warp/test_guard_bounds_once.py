"""The λ guard's two costly bounds (``lambda_no_worse_on_average``, ``lambda_least_on_screen``) are computed once
per input (``addon/warp/methods/warp_frustum.py``): lispsm and gmnpr of one B share them, with the same maps as
each computed alone, and any change of what they are computed from computes them anew."""
import dataclasses
import math

import numpy as np
import pytest

from addon.warp import Light, SceneBounds, View, WarpOptions, compute, focused_body
from addon.warp.geometry import look_along
from addon.warp.methods import warp_frustum
from addon.warp.methods.warp_frustum import FrameGeometry, WarpContext, guard_lambda

SCENE = SceneBounds.from_boxes([[[-50, -50, -0.1], [50, 50, 0.0]]] +
                               [[[x, y, 0.0], [x + 1.0, y + 1.0, 3.0]] for x in (-12.0, 0.0, 12.0)
                                for y in (5.0, 20.0, 35.0)])


@pytest.fixture
def calls(monkeypatch) -> list:
    """Each call of the two bounds, as it happens."""
    made = []
    for name in ("lambda_no_worse_on_average", "lambda_least_on_screen"):
        real = getattr(warp_frustum, name)
        monkeypatch.setattr(warp_frustum, name, lambda *a, real=real, name=name: made.append(name) or real(*a))
    return made


def test_lispsm_and_gmnpr_of_one_b_compute_the_bounds_once_and_give_the_maps_they_give_alone(calls):
    c2w = np.linalg.inv(look_along(np.array([0.3, -8.1, 6.2]), np.array([0.1, 1.0, -0.35]), np.array([0, 0, 1.0])))
    view = View.perspective(c2w, math.radians(60), 16 / 9, 0.1, 70, (1280, 720))
    light = Light("SUN", direction=np.array([0.3, 0.5, -1.0]))
    options = WarpOptions()
    body = focused_body(view, light, SCENE, options)
    lispsm = compute("lispsm", view, light, SCENE, options, body=body)
    first = len(calls)
    gmnpr = compute("gmnpr", view, light, SCENE, options, body=body)
    assert first > 0 and len(calls) == first
    # Each again on a new (equal) B and view: the same maps, bit for bit, as when computed first.
    view2 = dataclasses.replace(view, camera_to_world=view.camera_to_world.copy())
    body2 = focused_body(view2, light, SCENE, options)
    for name, setup in (("gmnpr", gmnpr), ("lispsm", lispsm)):
        again = compute(name, view2, light, SCENE, options, body=body2)
        assert [m.matrix.tobytes() for m in again.maps] == [m.matrix.tobytes() for m in setup.maps]


def _inputs(rng):
    axis = FrameGeometry(np.eye(4), (0.6, 0.8), -1.0, 12.0, (0.5, -3.0, 0.0), 12.0, 12.0, 0.7, None, 1.0)
    points = rng.uniform(0, 10, (40, 3))
    ctx = WarpContext(1.0, 30.0, (points, rng.uniform(0.5, 2, 40), rng.uniform(1, 30, 40)), rng.uniform(0, 3, 40),
                      phi=0.5)
    return axis, ctx, rng.uniform(0, 10, (8, 4)) * [1, 1, 1, 0] + [0, 0, 0, 1]


CHANGES = {
    "points": lambda a, c, b: (a, dataclasses.replace(c, visible=(c.visible[0] * 1.01, *c.visible[1:])), b),
    "weights": lambda a, c, b: (a, dataclasses.replace(c, visible=(c.visible[0], c.visible[1][::-1], c.visible[2])), b),
    "depths": lambda a, c, b: (a, dataclasses.replace(c, visible=(*c.visible[:2], c.visible[2] + 1.0)), b),
    "edges": lambda a, c, b: (a, dataclasses.replace(c, edges=c.edges[::-1].copy()), b),
    "no edges": lambda a, c, b: (a, dataclasses.replace(c, edges=None), b),
    "axis": lambda a, c, b: (dataclasses.replace(a, a=(0.8, 0.6)), c, b),
    "extent": lambda a, c, b: (dataclasses.replace(a, extent=13.0), c, b),
    "B": lambda a, c, b: (a, c, b[:6]),
    "no B": lambda a, c, b: (a, c, None),
}


@pytest.mark.parametrize("change", list(CHANGES))
def test_a_change_of_any_input_computes_the_bounds_anew(calls, change):
    axis, ctx, body_h = _inputs(np.random.default_rng(list(CHANGES).index(change)))   # (inputs no other test has)
    before = guard_lambda(0.0, 0.7, axis, ctx, 1.0, body_h)
    assert len(calls) == 2
    assert guard_lambda(0.0, 0.7, axis, ctx, 1.0, body_h) == before and len(calls) == 2      # asked again: kept
    new_axis, new_ctx, new_body = CHANGES[change](axis, ctx, body_h)
    guard_lambda(0.0, 0.7, new_axis, new_ctx, 1.0, new_body)
    assert len(calls) == 4, change                                                          # changed: computed anew
