"""The panel's Custom Visible Range against the camera's clip range, through the live state (panel, overlays,
scripts) and the render engine: a range wholly outside the clip range is refused by name, one that overlaps it is
taken where it does, for every method alike (the CLI refuses the same range as it reads the config:
tests/warp/test_cli.py)."""
import importlib
from types import SimpleNamespace

import bpy
import pytest

from ui_scenes import active_scene


@pytest.fixture(scope="module")
def m(lixel):
    def module(name):
        return importlib.import_module(f"{lixel.__name__}.addon.{name}")
    return SimpleNamespace(live=module("ui.live"), engine=module("render.engine"), gpu_context=module("gpu.context"),
                           types=module("warp.types"))


LENGTHS = {1000.0: "1 km", 2000.0: "2 km", 0.0: "0 m", 0.05: "5 cm"}


def _refusal(scene, near, far):
    return (f"Scene '{scene.name}' has a Visible Range from {LENGTHS[near]} to {LENGTHS[far]}, wholly outside the "
            f"clip range of camera '{scene.camera.name}' (10 cm to 30 m), so it holds nothing the camera sees: set it "
            f"within the clip range or turn Custom Visible Range off (Lixel panel > Method > Visible Range)")


@pytest.mark.parametrize("near, far", [(1000.0, 2000.0), (0.0, 0.05)])
@pytest.mark.parametrize("method", ["psm", "lispsm", "cascade"])
def test_a_visible_range_outside_the_clip_range_is_refused_naming_both(m, method, near, far):
    """A camera clipping at [0.1, 30] m and a Custom Visible Range of [1000, 2000] m (Δz = Visible): PSM and
    LiSPSM computed as if it were not there, the cascade said "no split of the view holds a visible receiver",
    naming no cause. Every method that reads the range now refuses it with the same message, naming the scene, the
    range, the camera and its clip range, and what to do; the user's settings are left as they were."""
    with active_scene("lixel_visible_range") as scene:
        scene.camera.data.clip_end = 30.0
        props = scene.lixel
        props.method, props.delta_z = method, "visible"
        props.use_visible_depth_range, props.visible_depth_range = True, (near, far)
        st = m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        assert not st.ok and st.error == _refusal(scene, near, far)
        assert tuple(props.visible_depth_range) == pytest.approx((near, far)) and props.use_visible_depth_range
        props.visible_depth_range = (5.0, 2000.0)           # overlapping the clip range: taken where it does
        st = m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        assert st.ok, st.error


@pytest.mark.parametrize("method", ["uniform", "plane_optimal"])
def test_a_method_that_does_not_read_the_visible_range_is_not_stopped_by_it(m, lixel, method):
    """Uniform and plane_optimal do not read the range and the panel hides it for them: a range left from LiSPSM
    outside the clip range does not stop them with a message about a field the user cannot see."""
    panel = importlib.import_module(f"{lixel.__name__}.addon.ui.panel")
    assert "visible_depth_range" not in panel.method_parameters(method)
    assert all("visible_depth_range" in panel.method_parameters(other) for other in ("psm", "lispsm", "cascade"))
    with active_scene("lixel_visible_range") as scene:
        scene.camera.data.clip_end = 30.0
        props = scene.lixel
        props.method, props.use_visible_depth_range, props.visible_depth_range = method, True, (1000.0, 2000.0)
        st = m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        assert st.ok, st.error


def test_a_cascade_with_no_receiver_in_the_visible_range_names_the_range(m):
    """[25, 2000] m overlaps the clip range [0.1, 30] m but the ground and the cube lie nearer than 25 m: the cascade
    splits only the range and has nothing to shadow. Its message said to aim the camera, and now names the range."""
    with active_scene("lixel_visible_range") as scene:
        scene.camera.data.clip_end = 30.0
        props = scene.lixel
        props.method, props.use_visible_depth_range, props.visible_depth_range = "cascade", True, (25.0, 2000.0)
        st = m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        assert not st.ok and st.error == (
            f"Camera '{scene.camera.name}' and light 'lixel_visible_range light' leave Lixel nothing to shadow: no "
            f"split of the view holds a visible receiver within the Visible Range: widen it (Lixel panel > Method > "
            f"Visible Range) or aim the camera (or the light) at the objects that receive shadows")
        props.method = "lispsm"                                 # (which does not split by it)
        assert m.live.update(scene, bpy.context.evaluated_depsgraph_get()).ok


def test_the_engine_refuses_the_same_range(m):
    """An F12 render (``render_depsgraph``, what the LIXEL engine runs) refuses the range as the panel does."""
    with active_scene("lixel_visible_range") as scene:
        scene.camera.data.clip_end = 30.0
        scene.lixel.method = "cascade"
        scene.lixel.use_visible_depth_range, scene.lixel.visible_depth_range = True, (1000.0, 2000.0)
        m.gpu_context.ensure_gpu_context()
        dg = bpy.context.evaluated_depsgraph_get()
        with pytest.raises(m.types.WarpError) as err:
            m.engine.render_depsgraph(dg, (64, 36))
        assert str(err.value) == _refusal(scene, 1000.0, 2000.0)
