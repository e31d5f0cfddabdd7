"""Registering and unregistering the extension 50 times leaves nothing behind:
no classes, app handlers, draw handlers, timers or properties (Blender 4.2
crashes at exit on anything left, shared notes §8.5)."""
import importlib
import sys

import bpy
import pytest

from conftest import ADDON_MODULE, disable_lixel, enable_lixel
from ui_scenes import active_scene

CYCLES = 50


def lixel_callables_in_app_handlers():
    found = []
    for name in dir(bpy.app.handlers):
        lst = getattr(bpy.app.handlers, name)
        if isinstance(lst, list):
            found += [(name, fn) for fn in lst if getattr(fn, "__module__", "").startswith(ADDON_MODULE)]
    return found


def lixel_functions(modules):
    for mod in modules:
        for value in vars(mod).values():
            if callable(value) and getattr(value, "__module__", "") == mod.__name__:
                yield value


def registered_state():
    root = sys.modules[ADDON_MODULE]
    names = ("addon.ui.properties", "addon.ui.preferences", "addon.ui.operators", "addon.ui.panel", "addon.ui.overlays",
             "addon.ui.live", "addon.render.engine")
    mods = [importlib.import_module(f"{root.__name__}.{n}") for n in names]
    classes = [c for m in mods for c in getattr(m, "classes", ())]
    return mods, classes


def assert_clean(mods, classes):
    assert [c.__name__ for c in classes if c.is_registered] == []
    for c in classes:
        assert getattr(bpy.types, c.__name__, None) is None or not c.is_registered
    assert lixel_callables_in_app_handlers() == []
    overlays = next(m for m in mods if m.__name__.endswith("overlays"))
    assert overlays.draw_handlers_active() == ()
    assert [f.__name__ for f in lixel_functions(mods) if bpy.app.timers.is_registered(f)] == []
    assert not hasattr(bpy.types.Scene, "lixel")
    assert "lixel" not in bpy.types.Scene.bl_rna.properties.keys()
    assert not hasattr(bpy.types, "LIXEL_OT_refresh")
    assert "LIXEL" not in {getattr(e, "bl_idname", None) for e in bpy.types.RenderEngine.__subclasses__()
                          if e.is_registered}


def test_fifty_register_unregister_cycles_leave_nothing(lixel):
    with active_scene("lixel_lifecycle"):
        for i in range(CYCLES):
            mods, classes = registered_state()
            assert all(c.is_registered for c in classes)
            assert hasattr(bpy.types.Scene, "lixel")
            assert len(lixel_callables_in_app_handlers()) == 4   # depsgraph update, frame change, load pre/post
            if i % 10 == 0:  # switch overlays on, so draw handlers and live state exist when unregistering
                bpy.context.scene.lixel.show_body = bpy.context.scene.lixel.show_frusta = False
                assert bpy.ops.lixel.toggle_overlay(overlay="show_body") == {"FINISHED"}
                assert bpy.ops.lixel.toggle_overlay(overlay="show_frusta") == {"FINISHED"}
                overlays = next(m for m in mods if m.__name__.endswith("overlays"))
                assert overlays.draw_handlers_active() == ("pixel", "view")
                live = next(m for m in mods if m.__name__.endswith(".live"))
                live.refine_when_resting()                      # a drag's refinement still pending
                assert live.refinement_pending()
            disable_lixel()
            try:
                assert_clean(mods, classes)
            finally:
                enable_lixel()  # the other tests need it enabled whatever happens here
    assert hasattr(bpy.types.Scene, "lixel")


def test_file_load_drops_draw_handlers_and_state(lixel, tmp_path):
    overlays = importlib.import_module(f"{ADDON_MODULE}.addon.ui.overlays")
    live = importlib.import_module(f"{ADDON_MODULE}.addon.ui.live")
    with active_scene("lixel_load") as scene:
        assert bpy.ops.lixel.toggle_overlay(overlay="show_body") == {"FINISHED"}
        assert overlays.draw_handlers_active() == ("pixel", "view")
        assert live.state(scene) is not None
        overlays.on_load_pre()
        assert overlays.draw_handlers_active() == ()
        assert live.state(scene) is None
        overlays.on_load_post()  # the "file" still has the overlay on: handlers come back
        assert overlays.draw_handlers_active() == ("pixel", "view")
        scene.lixel.show_body = False
        overlays.sync_handlers()
        assert overlays.draw_handlers_active() == ()


def test_enabling_lixel_again_draws_the_overlays_its_scenes_show(lixel):
    """Disabled and enabled again (Preferences > Add-ons), Lixel drew none of the overlays the panel still showed
    on, until they were toggled off and on or a file was opened: the draw handlers come back with it."""
    with active_scene("lixel_reenable") as scene:
        assert bpy.ops.lixel.toggle_overlay(overlay="show_frusta") == {"FINISHED"}
        disable_lixel()
        enable_lixel()
        assert scene.lixel.show_frusta
        overlays = importlib.import_module(f"{ADDON_MODULE}.addon.ui.overlays")
        assert overlays.draw_handlers_active() == ("pixel", "view")
        scene.lixel.show_frusta = False
        overlays.sync_handlers()
        assert overlays.draw_handlers_active() == ()


def test_opening_a_file_with_overlays_on_restores_them(lixel, tmp_path):
    overlays = importlib.import_module(f"{ADDON_MODULE}.addon.ui.overlays")
    with_overlay, without = tmp_path / "overlay_on.blend", tmp_path / "overlay_off.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(without), copy=True)
    with active_scene("lixel_saved") as scene:
        scene.lixel.show_frusta = True
        bpy.ops.wm.save_as_mainfile(filepath=str(with_overlay), copy=True)
    bpy.ops.wm.open_mainfile(filepath=str(with_overlay), load_ui=False)
    assert any(s.lixel.show_frusta for s in bpy.data.scenes)
    assert overlays.draw_handlers_active() == ("pixel", "view")
    bpy.ops.wm.open_mainfile(filepath=str(without), load_ui=False)
    assert overlays.draw_handlers_active() == ()


def test_live_state_belongs_to_the_scene_not_its_name(lixel):
    """A renamed scene keeps its state; a new scene that takes a deleted scene's
    name starts with none (with live update off nothing would replace the old
    one), and the deleted scene's state is dropped at the next update."""
    live = importlib.import_module(f"{ADDON_MODULE}.addon.ui.live")
    with active_scene("lixel_named") as scene:
        scene.lixel.live_update = False
        st = live.update(scene)
        assert st.ok
        scene.name = "lixel_renamed"
        assert live.state(scene) is st
    with active_scene("lixel_renamed", light=None) as newcomer:  # the old scene is deleted; its name is free
        assert newcomer.name == "lixel_renamed"
        assert live.state(newcomer) is None
        assert not live.update(newcomer).ok  # no light: its own error, not the old scene's setup
        assert st not in live.states()


OTHER_SCENE = r"""
import importlib, sys
sys.path.insert(0, sys.argv[1])
import bpy
import conftest
from ui_scenes import build
live = importlib.import_module(conftest.enable_lixel().__name__ + ".addon.ui.live")
scene = bpy.data.scenes.new("Other")       # not the window's scene: Blender never evaluated its view layer
build(scene)
st = live.update(scene)
print("ok" if st.ok else st.error, flush=True)
conftest.disable_lixel()
"""


def test_the_state_of_a_scene_not_shown_is_computed_not_crashed_on():
    """``live.update(scene)`` without a depsgraph took ``scene.view_layers[0].depsgraph``: for a scene the window
    does not show, one Blender never evaluated, and Blender crashed (segmentation fault, 4.2 and 5.0) reading the
    camera's projection from it. It takes the scene's evaluated depsgraph (``describe.evaluated_depsgraph``)."""
    import subprocess
    from pathlib import Path
    r = subprocess.run([sys.executable, "-c", OTHER_SCENE, str(Path(__file__).resolve().parent)],
                       capture_output=True, text=True, timeout=240)
    assert r.returncode == 0, (r.returncode, r.stderr[-800:])
    assert r.stdout.strip().splitlines()[-1] == "ok"
