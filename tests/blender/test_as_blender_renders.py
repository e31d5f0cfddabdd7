"""The LIXEL engine renders what Blender's engines render where a demanding user would look: each frame of an
animation render with that frame's animated values (the render's depsgraph evaluates the frame, while the original
objects stay at the frame shown before the render started); a scene with an object far from the rest; a light
whose Ray Visibility > Diffuse is off (Cycles and EEVEE, measured in 4.2.23 and 5.0.1: it lights no diffuse
surface, the picture's mean 0.58 -> 0.05); a mirrored camera (Cycles renders the mirror image); and Motion Blur,
which Lixel does not render, is named."""
import math

import bpy
import numpy as np
import pytest

from ui_scenes import build, cube_mesh
from worlds import background, sky_world


@pytest.fixture
def scene(fresh_scene):
    """An empty scene rendered by Lixel under a grey sky (its Background's colour for the test to set or key)."""
    fresh_scene.render.engine = "LIXEL"
    fresh_scene.world = sky_world("lixel_test sky", (0.1, 0.1, 0.1))
    yield fresh_scene
    bpy.data.worlds.remove(fresh_scene.world)


READ = {"combined", "shadow_mask", "covered"}


def _render(engine, scene, **render_kw) -> list:
    """The watched renders of ``bpy.ops.render.render(**render_kw)``."""
    with engine.watch_renders(read=READ) as got:
        assert bpy.ops.render.render(scene=scene.name, **render_kw) == {"FINISHED"}
    return got


# --- animation -------------------------------------------------------------------------------------------------

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
    _key(background(scene.world).inputs["Color"], "default_value",
         {1: (0.05, 0.05, 0.05, 1.0), 3: (0.1, 0.2, 0.4, 1.0)})
    scene.frame_start, scene.frame_end = 1, 3


def test_each_frame_of_an_animation_render_has_that_frames_light_camera_and_world(engine, scene, tmp_path):
    """Lixel read the light's strength, colour, cone and blend, the camera's clip range and the world colour from
    the original objects: every frame of an animation render had frame 1's (the frame shown when it started), while
    the moved light and camera, read evaluated, were right. Each frame now equals a render of that frame alone."""
    _animate(scene)
    scene.frame_set(1)
    scene.render.filepath = str(tmp_path / "frame_")
    animated = _render(engine, scene, animation=True)
    alone = []
    for frame in (1, 2, 3):
        scene.frame_set(frame)
        alone += _render(engine, scene)
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
    got = _render(engine, scene)
    assert (f"Lixel: Scene '{scene.name}' has Motion Blur on: Lixel renders each frame at its one instant, unblurred "
            f"(switch Motion Blur off in Render properties with Cycles or EEVEE, or render there for blur)"
            ) in got[-1]["warnings"]
    scene.render.use_motion_blur = False
    got = _render(engine, scene)
    assert not any("Motion Blur" in w for w in got[-1]["warnings"])


# --- far objects, lights, cameras ----------------------------------------------------------------------------

@pytest.mark.parametrize("distance", [1.0e5, 1.0e7, 1.0e9])
def test_a_small_object_far_away_leaves_the_near_scene_as_it_was(engine, scene, distance):
    """A 1 m cube ``distance`` away, out of the camera's and the light's view: the scene's float32 origin was the
    centre of all the objects' boxes, half way to the cube, where float32 steps are up to distance / 2^24: at 1e5 m
    two edge pixels moved, at 1e7 m the ground and cube near the world origin were drawn in 0.5 m steps (1.6 % of
    the pixels changed), at 1e9 m they collapsed and the render was the world background ("the camera sees no
    shadow receiver")."""
    build(scene)
    scene.render.resolution_x, scene.render.resolution_y = 96, 54
    near = _render(engine, scene)[-1]
    far = bpy.data.objects.new("lixel_test far cube", cube_mesh("lixel_test far cube"))
    far.location = (-distance, distance, 0.0)
    scene.collection.objects.link(far)
    got = _render(engine, scene)[-1]
    assert near["result"].covered.mean() > 0.5 and not any("no shadow" in w for w in got["warnings"])
    np.testing.assert_array_equal(got["result"].covered, near["result"].covered)
    differ = np.abs(got["result"].shadow_mask - near["result"].shadow_mask) > 0.5
    assert differ.mean() < 0.002, differ.sum()


def test_a_light_invisible_to_diffuse_rays_lights_nothing_and_keeps_its_shadow_pass(engine, scene):
    """Lixel lit the surfaces with it as if the flag were on."""
    build(scene)
    scene.render.resolution_x, scene.render.resolution_y = 96, 54
    sun = scene.objects[f"{scene.name} light"]
    lit = _render(engine, scene)[-1]
    sun.visible_diffuse = False
    invisible = _render(engine, scene)[-1]
    sun.visible_diffuse, energy, sun.data.energy = True, sun.data.energy, 0.0
    dark = _render(engine, scene)[-1]
    assert lit["result"].combined.mean() > dark["result"].combined.mean() + 0.1
    np.testing.assert_array_equal(invisible["result"].combined, dark["result"].combined)
    np.testing.assert_array_equal(invisible["result"].shadow_mask, lit["result"].shadow_mask)
    assert lit["result"].shadow_mask.max() > 0.5 and energy > 0
    assert invisible["warnings"] == (
        f"Light '{sun.name}' has Diffuse off in its Ray Visibility: as in Cycles and EEVEE it lights no surface, so "
        f"its shadows show only in the Shadow pass (Object properties > Visibility > Ray Visibility)",)


@pytest.mark.parametrize("how", ["camera", "parent"])
def test_a_mirrored_camera_renders_the_mirror_image(engine, scene, how):
    """A camera scaled negatively (a mirrored rig: an X scale of -1 on it or a parent): Cycles renders the mirror
    image (measured in 5.0.1: the unmirrored picture flipped left to right, to sampling noise). Lixel's shadow pass
    was mirrored, but every surface rendered black: the pre-pass's normal, from the screen derivatives, pointed
    away from the viewer, and so away from the light too."""
    build(scene)
    scene.render.resolution_x, scene.render.resolution_y = 64, 36
    plain = _render(engine, scene)[-1]
    if how == "camera":
        scene.camera.scale.x = -1.0
    else:
        rig = bpy.data.objects.new("lixel_test mirror rig", None)    # where the camera was, mirrored
        scene.collection.objects.link(rig)
        rig.location, rig.rotation_euler = scene.camera.location, scene.camera.rotation_euler
        rig.scale.x = -1.0
        scene.camera.parent = rig
        scene.camera.location, scene.camera.rotation_euler = (0, 0, 0), (0, 0, 0)
    mirrored = _render(engine, scene)[-1]
    assert plain["result"].covered.mean() > 0.5 and plain["result"].shadow_mask.max() > 0.5
    np.testing.assert_array_equal(mirrored["result"].covered, plain["result"].covered[:, ::-1])
    np.testing.assert_allclose(mirrored["result"].shadow_mask, plain["result"].shadow_mask[:, ::-1], atol=0.02)
    np.testing.assert_allclose(mirrored["result"].combined, plain["result"].combined[:, ::-1], atol=0.02)
