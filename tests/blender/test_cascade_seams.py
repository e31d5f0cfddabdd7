"""A cascade's seams in the shading pass: across a split's blend band the shadow
fades from the split's map into the next split's (addon/warp/methods/cascade.py,
gpu_shaders/shade_frag.glsl LIXEL_BLENDS), and nowhere else does the band change
a pixel."""
import dataclasses
import importlib
import math

import numpy as np
import pytest


@pytest.fixture(scope="module")
def mods(lixel):
    imp = lambda name: importlib.import_module(f"{lixel.__name__}.{name}")  # noqa: E731
    imp("addon.gpu.context").ensure_gpu_context()

    class M:
        warp = imp("addon.warp")
        geometry = imp("addon.warp.geometry")
        scene_geometry = imp("addon.scene.geometry")
        pipeline = imp("addon.gpu.pipeline")
        settings = imp("addon.settings")
    return M


def _box(lo, hi):
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = np.array([[x, y, z] for z in (z0, z1) for y in (y0, y1) for x in (x0, x1)], dtype=np.float64)
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    return v, np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])


def test_the_blend_band_fades_one_split_into_the_next_and_changes_nothing_else(mods):
    m = mods
    # A ground and a row of posts down the view, a sun from the side: shadows cross every split boundary.
    parts = [("ground", *_box((-60, -10, -0.1), (60, 200, 0.0)), None)]
    for k, y in enumerate(np.arange(2.0, 120.0, 3.0)):
        parts.append((f"post{k}", *_box((-0.2 + 0.3 * k % 3, y, 0.0), (0.2 + 0.3 * k % 3, y + 0.4, 3.0)), None))
    geometry = m.scene_geometry.SceneGeometry.from_arrays(parts)
    boxes = np.array([[v.min(axis=0), v.max(axis=0)] for _, v, _, _ in parts])
    scene = m.warp.SceneBounds.from_boxes(boxes)
    c2w = np.linalg.inv(m.geometry.look_along([0.0, -3.0, 2.0], [0.0, 1.0, -0.12], [0.0, 0.0, 1.0]))
    view = m.warp.View.perspective(c2w, math.radians(50.0), 16 / 9, 0.1, 150.0, (320, 180))
    light = m.warp.Light("SUN", direction=np.array([0.9, 0.25, -0.5]))
    options = m.warp.WarpOptions(shadow_map_size=256, cascade_splits=3, cascade_blend=0.3)
    blended = m.warp.compute("cascade", view, light, scene, options)
    assert any(sm.blend_band > 0 for sm in blended.maps)
    hard = dataclasses.replace(blended, maps=[dataclasses.replace(sm, blend_band=0.0) for sm in blended.maps])
    settings = dataclasses.replace(m.settings.LixelSettings(), shadow=dataclasses.replace(
        m.settings.LixelSettings().shadow, pcf_kernel=1))
    read = {"shadow_raw", "covered", "eye_depth"}
    a = m.pipeline.render_shadows(view, light, blended, geometry, settings, read=read)
    b = m.pipeline.render_shadows(view, light, hard, geometry, settings, read=read)
    covered = np.asarray(a.covered, dtype=bool) & np.asarray(b.covered, dtype=bool)
    depth = np.asarray(a.eye_depth)
    in_band = np.zeros_like(covered)
    for sm in blended.maps:
        if sm.blend_band > 0:
            end = sm.view_depth_range[1]
            in_band |= (depth > end) & (depth < end + sm.blend_band)
    sa, sb = np.asarray(a.shadow_raw), np.asarray(b.shadow_raw)
    assert in_band[covered].sum() > 500, "the bands cover part of the picture"
    outside = covered & ~in_band
    assert np.array_equal(sa[outside], sb[outside]), "outside the bands the blend changes nothing"
    assert np.all((sa[covered] >= 0) & (sa[covered] <= 1))
    inside = covered & in_band
    assert (sa[inside] != sb[inside]).any(), "inside the bands the nearer split's map is faded in"
    assert ((sa[inside] > 0) & (sa[inside] < 1)).any(), "a hard 1x1 test becomes a mix of two maps there"
