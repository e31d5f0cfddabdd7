"""A camera drag in the viewport with the cascade: the live handlers compute the PSSM λ splits (cheap), one timer
refines to the adaptive splits when the view rests, and the refined state is what a fresh full update gives, bit for
bit. Operators and scripts always get the full result; file load, unregister, a deleted scene and live updates
switched off leave no timer touching anything (addon/ui/live.py, "While the view moves")."""
import dataclasses
import importlib
import types

import bpy
import numpy as np
import pytest

from conftest import disable_lixel, enable_lixel
from ui_scenes import active_scene


@pytest.fixture
def m(lixel):
    ns = types.SimpleNamespace()
    ns.live = importlib.import_module(f"{lixel.__name__}.addon.ui.live")
    ns.overlays = importlib.import_module(f"{lixel.__name__}.addon.ui.overlays")
    ns.warp = importlib.import_module(f"{lixel.__name__}.addon.warp")
    yield ns
    ns.live.cancel_refinement()


def assert_identical(a, b, where="state"):
    """Equal bit for bit: numpy arrays by their bytes, dataclasses/dicts/sequences item by item."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes(), where
    elif dataclasses.is_dataclass(a) and not isinstance(a, type):
        assert type(a) is type(b), where
        for f in dataclasses.fields(a):
            assert_identical(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), where
        for k in a:
            assert_identical(a[k], b[k], f"{where}[{k!r}]")
    elif isinstance(a, (list, tuple)):
        assert type(a) is type(b) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            assert_identical(x, y, f"{where}[{i}]")
    else:
        assert a == b or (a != a and b != b), f"{where}: {a!r} != {b!r}"


def computed(st):
    """What a state shows: the setup, B, the overlay geometry and the footprint."""
    return st.setup, st.body, st.geometry, st.footprint, st.method_used


def drag(scene, steps=3, dx=0.3):
    """Move the scene camera ``steps`` times, each through the depsgraph handler (as a mouse drag does)."""
    for _ in range(steps):
        scene.camera.location.x += dx
        bpy.context.view_layer.update()


def test_a_drag_computes_the_lambda_splits_and_the_rest_refines_to_a_fresh_full_update(m):
    with active_scene("lixel_drag") as scene:
        scene.lixel.method = "cascade"
        full = m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        assert not full.provisional and full.settings.warp.cascade_adaptive
        drag(scene)
        st = m.live.state(scene)
        assert st.provisional and "setup" in st.recomputed and m.live.refinement_pending()
        assert st.setup.diagnostics.extra["split_scheme"] == "practical"
        lam = m.warp.compute("cascade", st.view, st.light, st.bounds,
                             dataclasses.replace(st.settings.warp, cascade_adaptive=False), body=st.body)
        assert_identical(st.setup, lam, "setup")       # the λ cascade: same B, warps "auto", layout
        assert ("Splits", "PSSM λ while moving; refining") in m.live.readouts(st)
        moved_view = st.view

        assert m.live.refine_after_rest() is None      # the timer, as it fires when the view rests: once
        refined = m.live.state(scene)
        assert not refined.provisional and refined.view is moved_view and refined.recomputed == ("setup", "overlays")
        assert refined.setup.diagnostics.extra["split_scheme"] != "practical"   # the search moved the splits
        assert not any(label == "Splits" for label, _ in m.live.readouts(refined))
        shown = computed(refined)
        m.live.clear()
        fresh = m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        assert_identical(shown, computed(fresh))
        assert m.live.refine() == []                    # nothing provisional: nothing to do


def test_a_change_while_a_refinement_is_armed_rearms_the_one_timer(m):
    with active_scene("lixel_drag_rearm") as scene:
        scene.lixel.method = "cascade"
        m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        armed = []
        original = m.live.refine_when_resting
        m.live.refine_when_resting = lambda then=None: (armed.append(then), original(then))
        try:
            drag(scene, steps=4)
        finally:
            m.live.refine_when_resting = original
        assert armed == [m.overlays.tag_redraw] * 4 and m.live.refinement_pending()
        m.live.cancel_refinement()
        assert not m.live.refinement_pending()


def test_scrubbing_an_animated_camera_takes_the_lambda_splits_and_refines(m):
    """frame_change_post (scrubbing, playback, ``frame_set``) goes the handler's way: λ splits, then the refinement."""
    with active_scene("lixel_drag_scrub") as scene:
        scene.lixel.method = "cascade"
        cam = scene.camera
        cam.keyframe_insert("location", frame=1)
        cam.location.x += 1.0
        cam.keyframe_insert("location", frame=10)
        scene.frame_set(1)
        m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        for frame in (3, 6, 10):
            scene.frame_set(frame)
            st = m.live.state(scene)
            assert st.provisional and "setup" in st.recomputed and m.live.refinement_pending()
        assert m.live.refine_after_rest() is None and not m.live.state(scene).provisional
        shown = computed(m.live.state(scene))
        m.live.clear()
        assert_identical(shown, computed(m.live.update(scene, bpy.context.evaluated_depsgraph_get())))
        cam.animation_data_clear()


def test_operators_and_scripts_during_a_drag_get_the_full_result(m, tmp_path):
    with active_scene("lixel_drag_ops") as scene:
        scene.lixel.method = "cascade"
        m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        drag(scene)
        assert m.live.state(scene).provisional
        reference = computed(m.live.update(scene, bpy.context.evaluated_depsgraph_get(), changed=()))
        for run in (lambda: bpy.ops.lixel.toggle_overlay(overlay="show_body"),        # reuses a state if it can
                    lambda: bpy.ops.lixel.export_json(filepath=str(tmp_path / "m.json")),
                    lambda: bpy.ops.lixel.refresh(),
                    lambda: bpy.ops.lixel.compare()):
            drag(scene, steps=1, dx=0.0001)
            drag(scene, steps=1, dx=-0.0001)
            assert m.live.state(scene).provisional
            assert run() == {"FINISHED"}
            st = m.live.state(scene)
            assert not st.provisional and st.setup.diagnostics.extra["split_scheme"] != "practical"
            assert_identical(computed(st), reference)
        drag(scene, steps=1)
        # a script: settings (and camera) overrides, everything checked
        st = m.live.update(scene, bpy.context.evaluated_depsgraph_get(), settings=m.live.scene_settings(scene),
                           camera=scene.camera, changed=None)
        assert not st.provisional and st.setup.diagnostics.extra["split_scheme"] != "practical"
        scene.lixel.show_body = False


@pytest.mark.parametrize("method, settings", [("lispsm", {}), ("cascade", {"cascade_adaptive": False}),
                                              ("cascade", {"cascade_stable": True})])
def test_other_methods_and_no_split_search_are_computed_in_full_while_moving(m, method, settings):
    with active_scene("lixel_drag_other") as scene:
        scene.lixel.method = method
        for k, v in settings.items():
            setattr(scene.lixel, k, v)
        m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        drag(scene)
        st = m.live.state(scene)
        assert "setup" in st.recomputed and not st.provisional and not m.live.refinement_pending()
        shown = computed(st)
        m.live.clear()
        assert_identical(shown, computed(m.live.update(scene, bpy.context.evaluated_depsgraph_get())))


def test_live_updates_off_and_a_deleted_scene_are_not_refined(m):
    with active_scene("lixel_drag_paused") as scene:
        scene.lixel.method = "cascade"
        m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        drag(scene)
        scene.lixel.live_update = False
        assert m.live.refine() == [] and m.live.state(scene).provisional
        assert m.live.refine_after_rest() is None
        m.live.cancel_refinement()                      # as the timer's None does once it ran
        assert ("Splits", "PSSM λ while moving; live updates paused: Refresh for the adaptive splits") in \
            m.live.readouts(m.live.state(scene))
        assert bpy.ops.lixel.refresh() == {"FINISHED"} and not m.live.state(scene).provisional
        scene.lixel.live_update = True
    with active_scene("lixel_drag_deleted") as scene:
        scene.lixel.method = "cascade"
        m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        drag(scene)
        assert m.live.refinement_pending()
    # the scene is gone (active_scene removed it), its state still held until the next update
    assert any(st.provisional for st in m.live.states())
    assert m.live.refine() == [] and m.live.refine_after_rest() is None


def test_load_pre_and_unregister_leave_no_timer(m):
    with active_scene("lixel_drag_load") as scene:
        scene.lixel.method = "cascade"
        m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        drag(scene)
        assert m.live.refinement_pending()
        m.overlays.on_load_pre()
        assert not m.live.refinement_pending() and m.live.states() == ()
        m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        drag(scene)
        timer = m.live.refine_after_rest
        assert bpy.app.timers.is_registered(timer)
        disable_lixel()
        try:
            assert not bpy.app.timers.is_registered(timer)
        finally:
            enable_lixel()
