"""An animation render (Render > Render Animation, ``blender -b file.blend -a``) renders each frame with that
frame's animated values, as a render of that frame alone does: the render's depsgraph evaluates the frame, while
the original objects stay at the frame shown before the render started."""
import importlib
import math

import bpy
import numpy as np
import pytest

from ui_scenes import build


@pytest.fixture(scope="module")
def engine(lixel):
    return importlib.import_module(lixel.__name__ + ".addon.render.engine")


@pytest.fixture
def scene(fresh_scene):
    fresh_scene.render.engine = "LIXEL"
    fresh_scene.world = bpy.data.worlds.new("lixel_test animated sky")
    yield fresh_scene
    bpy.data.worlds.remove(fresh_scene.world)


def _key(datablock, attr, values):
    for frame, value in values.items():
        setattr(datablock, attr, value)
        datablock.keyframe_insert(attr, frame=frame)


def _animate(scene):
    """A spot keyed brighter, yellower, wider and softer, the camera's clip end keyed to cut the
    ground's far part, the world keyed bluer, over frames 1..3."""
    build(scene, light="SPOT")
    scene.render.resolution_x, scene.render.resolution_y = 96, 64
    spot = scene.objects[f"{scene.name} light"]
    _key(spot.data, "energy", {1: 500.0, 3: 4000.0})
    _key(spot.data, "color", {1: (1.0, 1.0, 1.0), 3: (1.0, 0.6, 0.2)})
    _key(spot.data, "spot_size", {1: math.radians(40), 3: math.radians(110)})
    _key(spot.data, "spot_blend", {1: 0.0, 3: 0.8})
    _key(scene.camera.data, "clip_end", {1: 60.0, 3: 9.0})
    _key(scene.world, "color", {1: (0.05, 0.05, 0.05), 3: (0.1, 0.2, 0.4)})
    scene.frame_start, scene.frame_end = 1, 3


def test_each_frame_of_an_animation_render_has_that_frames_light_camera_and_world(engine, scene, tmp_path):
    """Lixel read the light's strength, colour, cone and blend, the camera's clip range and the world colour from
    the original objects: every frame of an animation render had frame 1's (the frame shown when it started), while
    the moved light and camera, read evaluated, were right. Each frame now equals a render of that frame alone."""
    _animate(scene)
    scene.frame_set(1)
    scene.render.filepath = str(tmp_path / "frame_")
    with engine.watch_renders(read={"combined", "shadow_mask", "covered"}) as animated:
        assert bpy.ops.render.render(scene=scene.name, animation=True) == {"FINISHED"}
    alone = []
    for frame in (1, 2, 3):
        scene.frame_set(frame)
        with engine.watch_renders(read={"combined", "shadow_mask", "covered"}) as got:
            assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
        alone += got
    assert len(animated) == len(alone) == 3
    first, last = alone[0]["result"], alone[2]["result"]
    assert last.covered.mean() < first.covered.mean() - 0.05            # the clip end cuts the ground's far part
    assert not np.allclose(first.combined, last.combined, atol=0.05)
    for frame, (a, b) in enumerate(zip(animated, alone), start=1):
        for image in ("combined", "shadow_mask", "covered"):
            np.testing.assert_array_equal(getattr(a["result"], image), getattr(b["result"], image),
                                          err_msg=f"frame {frame}: {image}")


def test_motion_blur_asked_for_is_named_not_silently_left_out(engine, scene):
    """Motion Blur switched on (with Cycles or EEVEE, whose panel sets it) blurs what moves there; Lixel rendered the
    frame's one instant without a word. It still does, and says so."""
    _animate(scene)
    scene.render.use_motion_blur = True
    with engine.watch_renders() as got:
        assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    assert (f"Lixel: Scene '{scene.name}' has Motion Blur on: Lixel renders each frame at its one instant, unblurred "
            f"(switch Motion Blur off in Render properties with Cycles or EEVEE, or render there for blur)"
            ) in got[-1]["warnings"]
    scene.render.use_motion_blur = False
    with engine.watch_renders() as got:
        assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    assert not any("Motion Blur" in w for w in got[-1]["warnings"])
