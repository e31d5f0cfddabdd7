"""Reporting-only diagnostics are computed when first read, once, and read the
same as if they had been computed up front ("model only what a scene needs"):
a warped frame pays for its warp frustum's corners, its projection centre and
B's middle vector only when something looks at them."""
import json
import math

import numpy as np
import pytest

import addon.warp.methods.warp_frustum as warp_frustum
from addon.warp import Light, SceneBounds, View, WarpOptions, compute, intersection_body
from addon.warp.geometry import clip_volume_corners, look_along
from addon.cli.output import diagnostics_json, setup_json
from addon.warp.diagnostics import Diagnostics, Extra, OnRead

SCENE = SceneBounds.from_boxes([[[-50.0, -50.0, -0.1], [50.0, 50.0, 0.0]]]
                               + [[[x, y, 0.0], [x + 1.0, y + 1.0, 3.0]] for x in (-12.0, 0.0, 12.0) for y in (5.0, 20.0)])


def _view():
    c2w = np.linalg.inv(look_along(np.array([0.0, -10.0, 2.0]), np.array([0.0, 1.0, -0.2]), np.array([0.0, 0.0, 1.0])))
    return View.perspective(c2w, math.radians(60.0), 16 / 9, 0.1, 70.0, (1280, 720))


LIGHTS = [Light("SUN", direction=[0.3, 0.5, -0.8]), Light("POINT", position=[4.0, 10.0, 8.0])]


class Counting:
    def __init__(self, fn):
        self.fn, self.calls = fn, 0

    def __call__(self, *args):
        self.calls += 1
        return self.fn(*args)


def test_a_value_reported_on_read_is_computed_on_first_read_and_kept():
    calls = []
    d = Diagnostics("x")
    d.warp_frustum_corners = OnRead(lambda: calls.append("corners") or np.ones((8, 3)))
    d.extra["centre"] = OnRead(lambda: calls.append("centre") or np.zeros(3))
    d.extra["plain"] = 1.5
    assert calls == []
    assert d.extra.get("centre").tolist() == [0.0, 0.0, 0.0]
    assert d.extra["centre"].tolist() == [0.0, 0.0, 0.0]
    assert calls == ["centre"]
    assert d.warp_frustum_corners.shape == (8, 3) and d.warp_frustum_corners.shape == (8, 3)
    assert calls == ["centre", "corners"]


@pytest.mark.parametrize("read", [dict, lambda e: {**e}, lambda e: dict(e.items()), lambda e: e.copy(),
                                  lambda e: dict(zip(e.keys(), e.values()))])
def test_every_way_of_reading_extra_sees_values_not_promises(read):
    extra = Extra(a=OnRead(lambda: 2.0), b="text")
    assert read(extra) == {"a": 2.0, "b": "text"}


def test_extra_given_as_a_plain_dict_reads_through_too():
    d = Diagnostics("x", extra={"later": OnRead(lambda: [1, 2])})
    assert isinstance(d.extra, Extra) and d.extra["later"] == [1, 2]
    assert diagnostics_json(d)["later"] == [1, 2]


@pytest.mark.parametrize("light", LIGHTS, ids=["sun", "point"])
@pytest.mark.parametrize("method", ["lispsm", "gmnpr", "glpr"])
def test_a_warped_frame_computes_its_report_only_when_read(monkeypatch, light, method):
    view = _view()
    body = intersection_body(view, light, SCENE)
    corners = Counting(warp_frustum.clip_volume_corners)
    centre = Counting(warp_frustum.projection_centre)
    monkeypatch.setattr(warp_frustum, "clip_volume_corners", corners)
    monkeypatch.setattr(warp_frustum, "projection_centre", centre)
    setup = compute(method, view, light, SCENE, WarpOptions(), body=body)
    assert (corners.calls, centre.calls) == (0, 0) and "volume_centroid" not in body.__dict__

    diag = setup.diagnostics
    # the corners of the first warped map's clip volume
    assert any(np.allclose(diag.warp_frustum_corners, clip_volume_corners(m.matrix)) for m in setup.maps)
    middle = body.volume_centroid - view.position
    assert np.allclose(diag.extra["middle_vector"], middle / np.linalg.norm(middle))
    assert diag.extra["projection_centre"] is None or np.all(np.isfinite(diag.extra["projection_centre"]))
    json.dumps(setup_json(setup), allow_nan=False)
    assert (corners.calls, centre.calls) == (1, 1)      # once each


def test_the_middle_vector_option_still_steers_the_warp():
    view, light = _view(), LIGHTS[0]
    body = intersection_body(view, light, SCENE)
    plain = compute("lispsm", view, light, SCENE, WarpOptions(), body=body)
    middle = compute("lispsm", view, light, SCENE, WarpOptions(middle_vector=True), body=body)
    assert not np.allclose(plain.maps[0].matrix, middle.maps[0].matrix)
