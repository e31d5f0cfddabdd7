"""An object far from the rest of the scene (a moon, a distant landmark, a stray vertex) changes nothing of what the
camera sees near it: the GPU draws in float32 relative to one origin per scene, and that origin stays with the
bulk of the scene, as Cycles' world origin keeps what is near it precise."""
import importlib

import bpy
import numpy as np
import pytest

from ui_scenes import build, cube_mesh


@pytest.fixture(scope="module")
def engine(lixel):
    return importlib.import_module(lixel.__name__ + ".addon.render.engine")


def _render(engine, scene):
    with engine.watch_renders(read={"combined", "shadow_mask", "covered"}) as got:
        assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    return got[-1]


@pytest.mark.parametrize("distance", [1.0e5, 1.0e7, 1.0e9])
def test_a_small_object_far_away_leaves_the_near_scene_as_it_was(engine, fresh_scene, distance):
    """A 1 m cube ``distance`` away, out of the camera's and the light's view: the scene's float32 origin was the
    centre of all the objects' boxes, half way to the cube, where float32 steps are up to distance / 2^24: at 1e5 m
    two edge pixels moved, at 1e7 m the ground and cube near the world origin were drawn in 0.5 m steps (1.6 % of
    the pixels changed), at 1e9 m they collapsed and the render was the world background ("the camera sees no
    shadow receiver")."""
    scene = fresh_scene
    build(scene)
    scene.render.engine = "LIXEL"
    scene.render.resolution_x, scene.render.resolution_y = 96, 54
    near = _render(engine, scene)
    far = bpy.data.objects.new("lixel_test far cube", cube_mesh("lixel_test far cube"))
    far.location = (-distance, distance, 0.0)
    scene.collection.objects.link(far)
    got = _render(engine, scene)
    assert near["result"].covered.mean() > 0.5 and not any("no shadow" in w for w in got["warnings"])
    np.testing.assert_array_equal(got["result"].covered, near["result"].covered)
    differ = np.abs(got["result"].shadow_mask - near["result"].shadow_mask) > 0.5
    assert differ.mean() < 0.002, differ.sum()
