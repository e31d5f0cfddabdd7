"""Scene properties > Units: Lixel computes in Blender units, so a Unit Scale changes no result, and the lengths the
Readouts panel shows (the focus's depth range, a cascade's split depths) are Blender's, in the scene's unit system
(a Unit Scale of 0.01 shows 100 units as 1 m). The panel printed the units as metres ("0.1–25 m" where Blender's own
fields read 1 mm to 25 cm)."""
import importlib
import re

import bpy
import numpy as np
import pytest

from ui_scenes import active_scene


@pytest.fixture(scope="module")
def live(lixel):
    return importlib.import_module(f"{lixel.__name__}.addon.ui.live")


def _lengths(text: str, system: str, scale: float) -> list:
    """The lengths in a readout (``a–b`` ranges), in Blender units."""
    shown = re.search(r"([^,–]+)–([^,]+)", text.split("depth ")[-1])
    return [bpy.utils.units.to_value(system, "LENGTH", s.strip()) / scale for s in shown.groups()]


@pytest.mark.parametrize("system, scale", [("METRIC", 1.0), ("METRIC", 0.01), ("IMPERIAL", 1.0),
                                           ("METRIC", 1000.0)])
def test_readouts_show_lengths_in_the_scenes_units_and_results_do_not_change(live, system, scale):
    with active_scene("lixel_units") as scene:
        scene.lixel.method = "cascade"
        assert bpy.ops.lixel.refresh() == {"FINISHED"}
        st = live.state(scene)
        before = [m.matrix.copy() for m in st.setup.maps]
        scene.unit_settings.system, scene.unit_settings.scale_length = system, scale
        assert bpy.ops.lixel.refresh() == {"FINISHED"}
        st = live.state(scene)
        assert all(np.array_equal(a, m.matrix) for a, m in zip(before, st.setup.maps, strict=True))
        rows = dict(live.readouts(st))
        z = st.setup.diagnostics.extra["splits"]
        splits = [label for label in rows if label.startswith("Split ")]
        assert len(splits) == len(z) - 1 >= 2
        for i, label in enumerate(splits):
            np.testing.assert_allclose(_lengths(rows[label], system, scale), z[i:i + 2], rtol=6e-3)
        np.testing.assert_allclose(_lengths(rows["Focus"], system, scale), st.body.visible.depth_range, rtol=6e-3)


UNIT_SYSTEMS = [("METRIC", 0.01), ("IMPERIAL", 1.0), ("METRIC", 1.0)]
"""Scene properties > Units for the messages' tests: centimetres, feet and inches, metres."""


@pytest.fixture(scope="module")
def describe(lixel):
    return importlib.import_module(f"{lixel.__name__}.addon.scene.describe")


def _in_units(scene, *texts) -> list:
    """Lengths as the scene's units write them, in Blender units."""
    u = scene.unit_settings
    return [bpy.utils.units.to_value(u.system, "LENGTH", t) / u.scale_length for t in texts]


def _units_scene(scene, system, scale):
    scene.unit_settings.system, scene.unit_settings.scale_length = system, scale
    bpy.context.view_layer.update()
    return scene


@pytest.mark.parametrize("system, scale", UNIT_SYSTEMS)
@pytest.mark.parametrize("near, far, shown", [
    (1e-4, 1e4, r"clips from (.+) to (.+), a range of 1:1e\+08, beyond what 32-bit float depth resolves"),
    (5.0, 2.0, r"clips at start (.+) and end (.+): the clip start must be positive and less than the clip end")])
def test_clip_range_refusals_name_the_clip_lengths_in_the_scenes_units(describe, system, scale, near, far, shown):
    """A clip range Lixel refuses is named as the camera's Clip Start and End fields show it: at a Unit Scale of
    0.01 the message said "clips from 0.0001 to 10000" where the fields read 1 µm and 100 m."""
    with active_scene("lixel_units") as scene:
        _units_scene(scene, system, scale)
        cam = scene.camera
        cam.data.clip_start, cam.data.clip_end = near, far
        with pytest.raises(describe.WarpError) as refused:
            describe.describe_view(cam, bpy.context.evaluated_depsgraph_get(), scene)
        lengths = re.search(shown, str(refused.value))
        assert lengths, str(refused.value)
        np.testing.assert_allclose(_in_units(scene, *lengths.groups()), [cam.data.clip_start, cam.data.clip_end],
                                   rtol=6e-3)


@pytest.mark.parametrize("system, scale", UNIT_SYSTEMS)
def test_the_lost_depth_note_names_its_lengths_in_the_scenes_units(live, system, scale):
    """The note on surfaces lost to 32-bit depth (clip 1e-6 to 10: lost beyond 4.56 units) printed bare Blender
    units; it reads as the Clip fields do, and the distance is the one Blender's fields would show."""
    with active_scene("lixel_units") as scene:
        _units_scene(scene, system, scale)
        scene.camera.data.clip_start, scene.camera.data.clip_end = 1e-6, 10.0
        assert bpy.ops.lixel.refresh() == {"FINISHED"}
        notes = [n for n in live.state(scene).notes if "32-bit depth" in n]
        assert len(notes) == 1
        lengths = re.search(r"clips from (.+) to (.+): 32-bit depth cannot tell its clip end from surfaces farther "
                            r"away than (.+), so they render as background", notes[0])
        assert lengths, notes[0]
        n, f = 1e-6, 10.0
        np.testing.assert_allclose(_in_units(scene, *lengths.groups()),
                                   [n, f, n * f / (n + 2.0 ** -23 * (f - n))], rtol=6e-3)


@pytest.mark.parametrize("system, scale", UNIT_SYSTEMS)
def test_a_too_far_object_and_a_bad_visible_range_are_named_in_the_scenes_units(describe, system, scale):
    """An object beyond the 1e12 units Lixel computes with, and a Visible Range whose far end is not beyond its near
    end: the messages said "reaches 3e+13 from the origin, beyond the 1e+12" and "(got 5.0, 2.0)" in Blender units."""
    with active_scene("lixel_units") as scene:
        _units_scene(scene, system, scale)
        scene.lixel.use_visible_depth_range, scene.lixel.visible_depth_range = True, (5.0, 2.0)
        with pytest.raises(describe.WarpError) as refused:
            scene.lixel.warp_options()
        lengths = re.search(r"Scene 'lixel_units' has a Visible Range from (.+) to (.+): its far end must lie beyond "
                            r"its near end \(Lixel panel > Method > Visible Range\)", str(refused.value))
        assert lengths, str(refused.value)
        np.testing.assert_allclose(_in_units(scene, *lengths.groups()), [5.0, 2.0], rtol=6e-3)
        scene.objects["lixel_units cube"].location = (0.0, -3e13, 0.0)
        bpy.context.view_layer.update()
        with pytest.raises(describe.WarpError) as refused:
            describe.describe_bounds(bpy.context.evaluated_depsgraph_get())
        lengths = re.search(r"Object 'lixel_units cube' reaches (.+) from the origin, beyond the (.+) Lixel can "
                            r"compute with", str(refused.value))
        assert lengths, str(refused.value)
        np.testing.assert_allclose(_in_units(scene, *lengths.groups()), [3e13 + 0.5, 1e12], rtol=6e-3)


@pytest.mark.parametrize("system, scale", UNIT_SYSTEMS)
def test_overlay_snapshot_notes_name_reaches_in_the_scenes_units(lixel, system, scale):
    """The observer snapshot's notes on what lies beyond its picture said "reaches 200 m" in Blender units."""
    snapshot = importlib.import_module(f"{lixel.__name__}.addon.ui.snapshot")

    class View:
        direction = np.array([0.0, 1.0, 0.0])
    box = np.array([[x, y, z] for x in (-1, 1) for y in (0, 10) for z in (0, 2)], dtype=float)
    geometry = {"view_corners": np.concatenate([box[:4], box[4:] * [20, 20, 1]]),
                "body_edges": np.stack([box[::2], box[1::2]], axis=1),
                "light_lines": np.array([[[0, 0, 0], [0, 0, 500.0]]]), "warp_lines": np.zeros((0, 2, 3))}
    with active_scene("lixel_units") as scene:
        _units_scene(scene, system, scale)
        _, notes = snapshot.observer_view_projection(geometry, View(), 1.6, scene=scene)
        centre = np.array([0.0, 5.0, 1.0])
        reaches = [np.linalg.norm(geometry["view_corners"] - centre, axis=1).max(),
                   np.linalg.norm(geometry["light_lines"].reshape(-1, 3) - centre, axis=1).max()]
        shown = [re.search(r" reach(?:es)? (.+) from the setup's centre, beyond the picture", n) for n in notes]
        assert all(shown) and len(shown) == 2, notes
        np.testing.assert_allclose(_in_units(scene, *(s.group(1) for s in shown)), reaches, rtol=6e-3)


@pytest.mark.parametrize("system, scale", UNIT_SYSTEMS)
@pytest.mark.parametrize("what", ["camera", "light"])
def test_a_too_far_camera_or_light_is_named_in_the_scenes_units(lixel, system, scale, what):
    """A camera or a point light beyond the 1e12 units Lixel computes with: Refresh said "The camera's position reaches
    2e+12 from the origin, beyond the 1e+12 Lixel can compute with", naming no camera and in Blender units (at a
    Unit Scale of 0.01 Blender's fields show 2e10 m)."""
    with active_scene("lixel_units", light="POINT") as scene:
        _units_scene(scene, system, scale)
        ob = scene.objects[f"lixel_units {what}"]
        ob.location.z = 2e12
        bpy.context.view_layer.update()
        with pytest.raises(RuntimeError) as refused:
            bpy.ops.lixel.refresh()
        lengths = re.search(rf"Lixel: {what.title()} 'lixel_units {what}' is (.+) from the origin, beyond the (.+) "
                            rf"Lixel can compute with: move it closer to the origin or scale the scene down",
                            str(refused.value))
        assert lengths, str(refused.value)
        np.testing.assert_allclose(_in_units(scene, *lengths.groups()), [2e12, 1e12], rtol=6e-3)


@pytest.mark.parametrize("system, scale", UNIT_SYSTEMS)
def test_n_opt_a_distance_is_shown_in_the_scenes_units(lixel, live, system, scale):
    """n_opt (LiSPSM's, Scherzer §4.4 Eq. 1: the warp's centre's distance from its near plane) is a length: the
    Readouts panel and the Compare Methods text printed it in bare Blender units ("n_opt 12.59" where, at a Unit
    Scale of 0.01, Blender's fields show 12.6 cm) beside the focus depths they already wrote in the scene's units;
    so did the comparison mosaic's tile labels (Compare Methods' picture, scripts/compare_methods.py)."""
    with active_scene("lixel_units") as scene:
        _units_scene(scene, system, scale)
        scene.lixel.method = "lispsm"
        assert bpy.ops.lixel.refresh() == {"FINISHED"}
        n_opt = live.state(scene).setup.diagnostics.n_opt
        assert n_opt is not None
        np.testing.assert_allclose(_in_units(scene, dict(live.readouts(live.state(scene)))["n_opt"]), [n_opt],
                                   rtol=6e-3)
        assert bpy.ops.lixel.compare(longest_side=16) == {"FINISHED"}
        table = bpy.data.texts["Lixel Comparison"].as_string()
        row = next(line for line in table.splitlines() if line.startswith("lispsm "))
        shown = re.match(r"lispsm +\S+ +\S+ +(.+?) +— +1 ", row)
        assert shown, row
        np.testing.assert_allclose(_in_units(scene, shown.group(1)), [n_opt], rtol=6e-3)
        rows = live.compare_methods(live.state(scene), ["lispsm"])        # the comparison mosaic's tile label
        label = importlib.import_module(f"{lixel.__name__}.addon.ui.renders").method_label(rows[0], scene)[1]
        shown = re.search(r"n_opt (.+?), texel footprint", label)
        assert shown, label
        np.testing.assert_allclose(_in_units(scene, shown.group(1)), [n_opt], rtol=6e-3)


@pytest.mark.parametrize("system, scale", UNIT_SYSTEMS)
def test_a_view_frustum_too_small_for_where_it_is_is_named_in_the_scenes_units(describe, system, scale):
    """A camera 1e9 units from the origin clipping from 0.01 to 0.2: Refresh said "The camera's view frustum is 0.29
    across at 1e+09 from the origin, below what float64 resolves there", naming no camera and in Blender units (at a
    Unit Scale of 0.01 Blender's fields show 2.9 mm and 10,000 km). Refresh, F12 and the scripts (each describes the
    camera first) say it of the camera by name, in the scene's units."""
    with active_scene("lixel_units") as scene:
        _units_scene(scene, system, scale)
        for ob in scene.objects:
            ob.location.x += 1e9
        scene.camera.data.clip_start, scene.camera.data.clip_end = 0.01, 0.2
        bpy.context.view_layer.update()
        with pytest.raises(RuntimeError) as refused:
            bpy.ops.lixel.refresh()
        lengths = re.search(r"Lixel: Camera 'lixel_units camera': its view frustum is (.+) across at (.+) from the "
                            r"origin, below what float64 resolves there: widen its clip range \(Camera properties > "
                            r"Lens > Clip\) or move the scene closer to the origin", str(refused.value))
        assert lengths, str(refused.value)
        scene.camera.location.x -= 1e9                                   # the same frustum at the origin
        bpy.context.view_layer.update()
        corners = describe.describe_view(scene.camera, bpy.context.evaluated_depsgraph_get(), scene).corners()
        np.testing.assert_allclose(_in_units(scene, *lengths.groups()),
                                   [np.linalg.norm(np.ptp(corners, axis=0)), 1e9 + 7.0], rtol=6e-3)
