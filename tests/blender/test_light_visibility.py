"""A light whose Ray Visibility > Diffuse is off (Object properties > Visibility) lights no diffuse surface in
Cycles and EEVEE (measured in 4.2.23 and 5.0.1: the picture's mean 0.58 -> 0.05, the world's light alone). Lixel's
surfaces are all diffuse: it renders such a light as lighting nothing, its shadows in the Shadow pass, and says so."""
import importlib

import bpy
import numpy as np
import pytest

from ui_scenes import build


@pytest.fixture(scope="module")
def engine(lixel):
    return importlib.import_module(lixel.__name__ + ".addon.render.engine")


def _render(engine, scene):
    with engine.watch_renders(read={"combined", "shadow_mask"}) as got:
        assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    return got[-1]


def test_a_light_invisible_to_diffuse_rays_lights_nothing_and_keeps_its_shadow_pass(engine, fresh_scene):
    """Lixel lit the surfaces with it as if the flag were on."""
    scene = fresh_scene
    build(scene)
    scene.render.engine = "LIXEL"
    scene.render.resolution_x, scene.render.resolution_y = 96, 54
    scene.world = bpy.data.worlds.new("lixel_test sky")
    scene.world.color = (0.1, 0.1, 0.1)
    try:
        sun = scene.objects[f"{scene.name} light"]
        lit = _render(engine, scene)
        sun.visible_diffuse = False
        invisible = _render(engine, scene)
        sun.visible_diffuse, energy, sun.data.energy = True, sun.data.energy, 0.0
        dark = _render(engine, scene)
    finally:
        bpy.data.worlds.remove(scene.world)
    assert lit["result"].combined.mean() > dark["result"].combined.mean() + 0.1
    np.testing.assert_array_equal(invisible["result"].combined, dark["result"].combined)
    np.testing.assert_array_equal(invisible["result"].shadow_mask, lit["result"].shadow_mask)
    assert lit["result"].shadow_mask.max() > 0.5 and energy > 0
    assert invisible["warnings"] == (
        f"Light '{sun.name}' has Diffuse off in its Ray Visibility: as in Cycles and EEVEE it lights no surface, so "
        f"its shadows show only in the Shadow pass (Object properties > Visibility > Ray Visibility)",)
