"""plane_optimal's notes name the receiver they speak of: the core names it "receiver box i", i its index among the
receivers B was built from, a number no user can look up (not even in a config: boxes out of view are not counted).
The panel and the comparison name the object, the CLI the config's ``boxes[k]`` (tests/warp/test_cli.py)."""
import contextlib
import importlib

import bpy
import pytest

from ui_scenes import _link, active_scene, cube_mesh


@pytest.fixture(scope="module")
def live(lixel):
    return importlib.import_module(f"{lixel.__name__}.addon.ui.live")


@contextlib.contextmanager
def towers():
    """A scene whose receivers in view are all tall (no flat top): its ground removed, a box far behind the camera
    first, then a tower (the flattest box in view) beside the cube."""
    with active_scene("lixel_towers") as scene:
        bpy.data.objects.remove(scene.objects["lixel_towers ground"])
        _link(scene, "Far Behind", cube_mesh("Far Behind"), location=(300.0, -300.0, 0.0))
        tower = _link(scene, "Tower", cube_mesh("Tower"), location=(-1.0, 0.5, 0.0))
        tower.scale = (2.0, 2.0, 1.5)
        scene.lixel.method = "plane_optimal"
        bpy.context.view_layer.update()
        yield scene


def test_the_flattest_receiver_is_named_by_its_object_in_the_panel_and_the_comparison(live):
    with towers() as scene:
        st = live.update(scene, bpy.context.evaluated_depsgraph_get())
        assert st.ok, st.error
        fallbacks = [value for label, value in live.readouts(st) if label == "Fallback"]
        assert any("the flattest, object 'Tower', is 75%" in f for f in fallbacks), fallbacks
        assert not any("receiver box" in f for f in fallbacks)
        row = live.compare_methods(st, ["plane_optimal"])[0]
        assert any("the flattest, object 'Tower', is 75%" in f for f in row["fallbacks"]), row["fallbacks"]


def test_the_default_planes_top_is_named_by_its_object(live):
    with active_scene("lixel_ground") as scene:
        _link(scene, "Far Behind", cube_mesh("Far Behind"), location=(300.0, -300.0, 0.0))
        scene.lixel.method = "plane_optimal"
        bpy.context.view_layer.update()
        st = live.update(scene, bpy.context.evaluated_depsgraph_get())
        assert st.ok, st.error
        d = st.setup.diagnostics
        assert "receiver box" not in repr(d.fallbacks) + repr(d.extra)
        assert d.extra["default_plane"] == "top of object 'lixel_ground ground'", d.extra["default_plane"]


def test_a_plane_of_interest_is_named_as_the_panel_lists_it(live, lixel):
    """The panel lists the planes of interest by what they were taken from ("Ground"; "Plane 1" where nothing is
    recorded); the notes said "planes[0]", and a bad plane's error "Plane of interest 'unnamed'"."""
    from test_ui_notes import IconLayout
    panel = importlib.import_module(f"{lixel.__name__}.addon.ui.panel")
    with active_scene("lixel_planes") as scene:
        scene.lixel.method = "plane_optimal"
        for point, source in (((0.0, 0.0, 1e6), "Ground"), ((0.0, 0.0, 0.0), "")):
            p = scene.lixel.planes.add()
            p.point, p.normal, p.source = point, (0.0, 0.0, 1.0), source
        st = live.update(scene, bpy.context.evaluated_depsgraph_get())
        assert st.ok, st.error
        fallbacks = [value for label, value in live.readouts(st) if label == "Fallback"]
        assert any("plane of interest 'Ground' has no visible part" in f for f in fallbacks), fallbacks
        assert not any("planes[" in f for f in fallbacks)
        log = []
        panel.draw_planes(IconLayout(log), scene.lixel)
        assert [e[1] for e in log if e[0] == "label" and e[1] in ("Ground", "Plane 1")] == ["Ground", "Plane 1"]
        scene.lixel.planes[1].normal = (0.0, 0.0, 0.0)
        st = live.update(scene, bpy.context.evaluated_depsgraph_get())
        assert "Plane of interest 'Plane 1' of scene 'lixel_planes' has a non-finite point or a zero normal" in st.error
