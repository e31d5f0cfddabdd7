"""Every entry point has one guard (addon/guard.py): a bug anywhere behind an
operator, the render engine, a draw callback or an app handler reaches the user
as one clear line, never as a traceback; the traceback goes to the debug log."""
import importlib
import logging

import bpy
import pytest

from ui_scenes import active_scene


class Boom(Exception):
    pass


def _explode(*_args, **_kw):
    raise Boom("a bug deep inside")


@pytest.fixture(scope="module")
def mods(lixel):
    class M:
        pass
    m = M()
    for name in ("live", "overlays"):
        setattr(m, name, importlib.import_module(f"{lixel.__name__}.addon.ui.{name}"))
    m.guard = importlib.import_module(f"{lixel.__name__}.addon.guard")
    m.engine = importlib.import_module(f"{lixel.__name__}.addon.render.engine")
    return m


@pytest.fixture
def scene(lixel, mods):
    with active_scene("lixel_guard") as sc:
        sc.render.resolution_x, sc.render.resolution_y = 48, 32
        yield sc
    mods.live.clear()


def test_a_bug_behind_an_operator_is_one_line_naming_it(scene, mods, monkeypatch, capfd, caplog):
    monkeypatch.setattr(mods.live, "focused_body", _explode)     # (the live state builds B with it)
    with caplog.at_level(logging.DEBUG):
        with pytest.raises(RuntimeError) as info:
            bpy.ops.lixel.refresh()
    msg = str(info.value)
    assert "unexpected error" in msg and "lixel_guard" in msg and "Boom: a bug deep inside" in msg
    assert "bug in Lixel" in msg
    assert "Traceback" not in capfd.readouterr().err
    # the traceback is in the log, at debug level
    debug = [r for r in caplog.records if r.levelno == logging.DEBUG and r.exc_info]
    assert debug and debug[-1].exc_info[0] is Boom


def test_a_bug_in_the_live_update_handler_prints_no_traceback(scene, mods, monkeypatch, capfd):
    assert bpy.ops.lixel.refresh() == {"FINISHED"}
    monkeypatch.setattr(mods.live, "scene_bounds", _explode)
    scene.objects["lixel_guard cube"].location.x += 0.5
    bpy.context.view_layer.update()  # runs depsgraph_update_post
    st = mods.live.state(scene)
    assert "unexpected error" in st.error and "Boom" in st.error
    assert "Traceback" not in capfd.readouterr().err


def test_handlers_and_draw_callbacks_swallow_bugs(scene, mods, monkeypatch, capfd):
    monkeypatch.setattr(mods.overlays, "_scene_state", _explode)
    assert mods.overlays.draw_view() is None
    assert mods.overlays.draw_pixel() is None
    monkeypatch.setattr(mods.overlays, "classify_updates", _explode)
    assert bpy.ops.lixel.refresh() == {"FINISHED"}
    scene.objects["lixel_guard cube"].location.x += 0.5
    bpy.context.view_layer.update()
    err = capfd.readouterr().err
    assert "Traceback" not in err


def test_a_bug_in_the_render_is_a_render_error_not_a_traceback(scene, mods, monkeypatch, capfd):
    scene.render.engine = "LIXEL"
    monkeypatch.setattr(mods.engine, "compute", _explode)
    with pytest.raises(RuntimeError, match=r"Lixel: unexpected error while rendering scene 'lixel_guard' \(Boom"):
        bpy.ops.render.render(scene=scene.name)
    assert "Traceback" not in capfd.readouterr().err


def test_a_warp_error_keeps_its_own_message(mods):
    from_types = importlib.import_module(mods.guard.__name__.rsplit(".", 1)[0] + ".warp.types")
    exc = from_types.WarpError("Camera 'C' has zero scale: set its scale to 1")
    assert mods.guard.user_message(exc, "anything") == "Camera 'C' has zero scale: set its scale to 1"
