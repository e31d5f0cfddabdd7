"""A camera scaled negatively (a mirrored rig, an X scale of -1 on it or a parent) renders the mirror image, as
Cycles does (measured in 5.0.1: its picture is the unmirrored one flipped left to right, to sampling noise)."""
import importlib

import bpy
import numpy as np
import pytest

from ui_scenes import active_scene


@pytest.fixture(scope="module")
def engine(lixel):
    return importlib.import_module(lixel.__name__ + ".addon.render.engine")


def _render(engine, scene):
    with engine.watch_renders(read={"combined", "shadow_mask", "covered"}) as got:
        assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    return got[-1]["result"]


@pytest.mark.parametrize("how", ["camera", "parent"])
def test_a_mirrored_camera_renders_the_mirror_image(engine, how):
    """Lixel's shadow pass was mirrored, but every surface rendered black: the pre-pass's normal, from the screen
    derivatives, pointed away from the viewer, and so away from the light too."""
    with active_scene("lixel_mirror") as scene:
        scene.render.engine = "LIXEL"
        scene.render.resolution_x, scene.render.resolution_y = 64, 36
        scene.world = bpy.data.worlds.new("lixel_test sky")
        scene.world.color = (0.1, 0.1, 0.1)
        try:
            plain = _render(engine, scene)
            if how == "camera":
                scene.camera.scale.x = -1.0
            else:
                rig = bpy.data.objects.new("lixel_mirror rig", None)    # where the camera was, mirrored
                scene.collection.objects.link(rig)
                rig.location, rig.rotation_euler = scene.camera.location, scene.camera.rotation_euler
                rig.scale.x = -1.0
                scene.camera.parent = rig
                scene.camera.location, scene.camera.rotation_euler = (0, 0, 0), (0, 0, 0)
            mirrored = _render(engine, scene)
        finally:
            bpy.data.worlds.remove(scene.world)
    assert plain.covered.mean() > 0.5 and plain.shadow_mask.max() > 0.5
    np.testing.assert_array_equal(mirrored.covered, plain.covered[:, ::-1])
    np.testing.assert_allclose(mirrored.shadow_mask, plain.shadow_mask[:, ::-1], atol=0.02)
    np.testing.assert_allclose(mirrored.combined, plain.combined[:, ::-1], atol=0.02)
