"""The viewport's live state (overlays, panel readouts, the shadowed picture) follows what the user does.

The timeline: a frame change (scrubbing, playback, ``scene.frame_set``) moves animated cameras, lights and objects,
and Blender announces it with ``frame_change_post``, not ``depsgraph_update_post``. An animation render's frames
(its own depsgraph) leave the viewport's state alone.

Edit Mode: a mesh being edited is still part of the scene. Its evaluated mesh is then a wrapper around the edit
mesh, whose faces and positions Blender's Python API shows only through ``Object.to_mesh()``; the live state and a
render in Edit Mode see what Object Mode sees."""
import importlib

import bpy
import numpy as np
import pytest

from ui_scenes import active_scene


@pytest.fixture(scope="module")
def m(lixel):
    class M:
        pass
    ns = M()
    ns.live = importlib.import_module(f"{lixel.__name__}.addon.ui.live")
    ns.describe = importlib.import_module(f"{lixel.__name__}.addon.scene.describe")
    ns.engine = importlib.import_module(f"{lixel.__name__}.addon.render.engine")
    return ns


def _described(m, scene):
    """The scene's view, light and bounds at the frame it shows."""
    return m.describe.describe_scene(bpy.context)


@pytest.mark.parametrize("what", ["camera", "light", "cube"])
def test_a_frame_change_moves_the_live_state_with_the_animation(m, what):
    """The camera or cube keyed to move, the sun to turn, between frames 1 and 10: after ``frame_set(10)`` the live state
    (B, the maps, the panel's readouts) was still frame 1's until something else changed the scene."""
    with active_scene("lixel_timeline") as scene:
        ob = {"camera": scene.camera, "light": scene.objects["lixel_timeline light"],
              "cube": scene.objects["lixel_timeline cube"]}[what]
        path = "rotation_euler" if what == "light" else "location"    # a sun turns
        ob.keyframe_insert(path, frame=1)
        getattr(ob, path).x -= 0.3 if what == "light" else 1.5
        ob.keyframe_insert(path, frame=10)
        scene.frame_set(1)
        assert m.live.update(scene, bpy.context.evaluated_depsgraph_get()).ok
        def inputs(view, light, bounds):
            return view.camera_to_world, light.direction, bounds.casters

        before = inputs(*_described(m, scene))
        scene.frame_set(10)
        now = inputs(*_described(m, scene))
        assert any(not np.array_equal(a, b) for a, b in zip(before, now))     # the frame did move something
        st = m.live.state(scene)
        np.testing.assert_equal(inputs(st.view, st.light, st.bounds), now)


def test_an_animation_render_leaves_the_viewports_state_at_the_frame_shown(m, tmp_path):
    """The render's own frames (its depsgraph, in RENDER mode) are not the viewport's: its state stays at the frame
    the viewport shows."""
    with active_scene("lixel_timeline_render") as scene:
        cam = scene.camera
        cam.keyframe_insert("location", frame=1)
        cam.location.x -= 1.5
        cam.keyframe_insert("location", frame=3)
        scene.frame_start, scene.frame_end = 1, 3
        scene.render.engine = "LIXEL"
        scene.render.resolution_x, scene.render.resolution_y = 32, 18
        scene.render.filepath = str(tmp_path / "frame_")
        scene.frame_set(1)
        assert m.live.update(scene, bpy.context.evaluated_depsgraph_get()).ok
        shown = m.live.state(scene).view.camera_to_world.copy()
        updates = []
        original = m.live.update
        m.live.update = lambda *a, **kw: (updates.append(a[1].mode if len(a) > 1 else None), original(*a, **kw))[1]
        try:
            assert bpy.ops.render.render(scene=scene.name, animation=True) == {"FINISHED"}
        finally:
            m.live.update = original
        assert "RENDER" not in updates
        assert scene.frame_current == 1
        np.testing.assert_array_equal(m.live.state(scene).view.camera_to_world, shown)


def _seen(m, scene):
    """The live state's casters and first map, and a render's shadow pass, of the scene as it is."""
    st = m.live.update(scene, bpy.context.evaluated_depsgraph_get())
    assert st.ok, st.error
    with m.engine.watch_renders(read={"shadow_mask"}) as got:
        assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    return st.bounds.casters.copy(), st.setup.maps[0].matrix.copy(), got[-1]["result"].shadow_mask


@pytest.mark.parametrize("modifier", [None, "SUBSURF", "BEVEL", "ARRAY"])
def test_a_mesh_in_edit_mode_is_seen_as_in_object_mode(m, modifier):
    """The cube in Edit Mode: without modifiers it dropped out of the scene (its wrapper shows no faces), so it cast
    no shadow while being edited; with a Subdivision, Bevel or Array modifier every operator, the panel and the
    overlays said "unexpected error ... KeyError: 'position' ... a bug in Lixel"."""
    with active_scene("lixel_edit") as scene:
        scene.render.engine = "LIXEL"
        scene.render.resolution_x, scene.render.resolution_y = 64, 36
        cube = scene.objects["lixel_edit cube"]
        if modifier:
            cube.modifiers.new("lixel_test", modifier)
        object_mode = _seen(m, scene)
        bpy.context.view_layer.objects.active = cube
        cube.select_set(True)
        bpy.ops.object.mode_set(mode="EDIT")
        try:
            edit_mode = _seen(m, scene)
            assert bpy.ops.lixel.refresh() == {"FINISHED"}
        finally:
            bpy.ops.object.mode_set(mode="OBJECT")
        assert object_mode[2].max() > 0.5                       # the cube casts a shadow
        for a, b in zip(object_mode, edit_mode):
            np.testing.assert_array_equal(a, b)
