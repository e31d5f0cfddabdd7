"""A mesh being edited (Edit Mode) is still part of the scene: its evaluated mesh is then a wrapper around the edit
mesh, whose faces and positions Blender's Python API shows only through ``Object.to_mesh()``. The viewport's live
state and a render in Edit Mode see what Object Mode sees."""
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
    ns.engine = importlib.import_module(f"{lixel.__name__}.addon.render.engine")
    return ns


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
