"""The LIXEL render engine through ``bpy.ops.render.render`` (what F12 and
``blender -b file.blend -E LIXEL -f 1`` run)."""
import importlib
import math
import re
from pathlib import Path

import bpy
import numpy as np
import pytest
from mathutils import Matrix, Vector

from worlds import sky_world


@pytest.fixture
def scene(fresh_scene):
    fresh_scene.render.engine = "LIXEL"
    fresh_scene.render.resolution_x, fresh_scene.render.resolution_y = 96, 64
    fresh_scene.render.resolution_percentage = 100
    yield fresh_scene


def add(scene, name, data):
    ob = bpy.data.objects.new(name, data)
    scene.collection.objects.link(ob)
    return ob


def cube_mesh(name, size, z):
    me = bpy.data.meshes.new(name)
    h = size / 2
    me.from_pydata([(x, y, z + zz) for x in (-h, h) for y in (-h, h) for zz in (-h, h)], [],
                   [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])
    return me


def build(scene, with_light=True, with_mesh=True, with_camera=True):
    if with_mesh:
        ground = bpy.data.meshes.new("Ground")
        ground.from_pydata([(-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0)], [], [(0, 1, 2, 3)])
        add(scene, "Ground", ground)
        add(scene, "Box", cube_mesh("Box", 1.5, 1.2))
    if with_camera:
        cam = add(scene, "Cam", bpy.data.cameras.new("Cam"))
        cam.location = (0, -7, 6)
        cam.rotation_euler = (Vector((0, 0, 0)) - cam.location).to_track_quat("-Z", "Y").to_euler()
        scene.camera = cam
    if with_light:
        sun = add(scene, "Sun", bpy.data.lights.new("Sun", "SUN"))
        sun.rotation_euler = (math.radians(30), 0, math.radians(20))
        sun.data.energy = 3.0


def test_render_writes_lixel_shadows(engine, scene, tmp_path, load_pixels):
    build(scene)
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(tmp_path / "frame.exr")
    with engine.watch_renders() as got:
        assert bpy.ops.render.render(write_still=True, scene=scene.name) == {"FINISHED"}
    last = got[-1]
    assert last["scene"] == scene.name
    res = last["result"]
    assert res.combined.shape == (64, 96, 4)
    assert 0.01 < res.shadow_mask.mean() < 0.5
    assert res.counts.casters_drawn == 2
    assert res.footprint_heatmap is None and res.shadow_map_preview is None, "debug passes are off by default"
    assert res.covered is None and res.world_position is None, "the engine reads back only its passes"
    np.testing.assert_allclose(load_pixels(tmp_path / "frame.exr")[..., :3], res.combined[..., :3], atol=1e-5)


@pytest.mark.parametrize("crop", [True, False])
def test_a_render_border_gets_its_part_of_the_frame(engine, scene, tmp_path, capfd, crop, load_pixels):
    """Render Region (Output properties > Format): Blender's result holds only the border's pixels; the engine
    fills it with that part of the frame, cropped to it in the file or not."""
    build(scene)
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(tmp_path / "frame.exr")
    scene.render.use_border, scene.render.use_crop_to_border = True, crop
    r = scene.render
    r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = 0.21, 0.77, 0.13, 0.59
    with engine.watch_renders() as got:
        assert bpy.ops.render.render(write_still=True, scene=scene.name) == {"FINISHED"}
    assert "Traceback" not in capfd.readouterr().err
    x0, x1, y0, y1 = int(0.21 * 96), int(0.77 * 96), int(0.13 * 64), int(0.59 * 64)
    px = load_pixels(tmp_path / "frame.exr")
    part = px[..., :3] if crop else px[y0:y1, x0:x1, :3]
    assert px.shape[1::-1] == ((x1 - x0, y1 - y0) if crop else (96, 64))
    np.testing.assert_allclose(part, got[-1]["result"].combined[y0:y1, x0:x1, :3], atol=1e-5)
    assert part.max() > 0


def test_view_layer_switches_choose_the_passes(engine, scene):
    """Shadow on, Footprint and Shadow Map off by default; each switch adds its
    pass (and only then is it drawn and read back)."""
    build(scene)
    switches = scene.view_layers[0].lixel_passes
    assert (switches.shadow, switches.footprint, switches.shadow_map) == (True, False, False)
    switches.footprint = switches.shadow_map = True
    switches.shadow = False
    try:
        with engine.watch_renders() as got:
            assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
        res = got[-1]["result"]
        assert res.footprint_heatmap.shape == (64, 96, 4) and res.shadow_map_preview.shape == (64, 96)
        assert res.shadow_mask is None
        covered = res.footprint_heatmap[..., :3].any(axis=-1)        # black where nothing is seen
        assert covered.mean() > 0.2
        assert 0.0 < res.shadow_map_preview.min() < res.shadow_map_preview.max() <= 1.0
    finally:
        switches.footprint = switches.shadow_map = False
        switches.shadow = True


def test_settings_come_from_the_scene(engine, scene):
    build(scene)
    props = getattr(scene, "lixel", None)
    if props is None:
        assert engine.scene_settings(scene) == engine.LixelSettings()
        return
    props.method = "uniform"
    props.pcf_kernel = 1
    props.shadow_map_size = (512, 512)
    with engine.watch_renders() as got:
        bpy.ops.render.render(scene=scene.name)
    last = got[-1]
    assert last["method"] == "uniform"
    assert last["settings"].shadow.pcf_kernel == 1
    assert tuple(last["setup"].maps[0].size) == (512, 512)
    assert set(np.unique(last["result"].shadow_mask)) <= {0.0, 1.0}  # k = 1: no PCF levels


def test_second_render_uploads_nothing(engine, scene):
    """F12 again on an unchanged scene uploads nothing and computes B and the
    warp no more (the same setup); a moved camera computes them again, and so
    does an edited mesh whose box is unchanged (what the camera sees changed)."""
    build(scene)
    warps = engine.shared_warps()
    with engine.watch_renders() as got:
        bpy.ops.render.render(scene=scene.name)
        computed = warps.computes
        bpy.ops.render.render(scene=scene.name)
        assert warps.computes == computed, "B and the warp were computed again for an unchanged frame"
        scene.camera.location.x += 0.3
        bpy.ops.render.render(scene=scene.name)
        assert warps.computes == computed + 1
        box = next(o for o in scene.objects if o.name.startswith("Box"))
        box.data.vertices[0].co.x += 0.3      # (-h, -h, ·) moves inwards: the box's bounds stay
        box.data.update()
        bpy.ops.render.render(scene=scene.name)
        assert warps.computes == computed + 2
    (first, second, moved, _), setups = ([g[k] for g in got] for k in ("result", "setup"))
    c = second.counts
    assert (c.uploads, c.matrix_uploads, c.list_uploads, c.target_allocations) == (0, 0, 0, 0)
    np.testing.assert_array_equal(first.shadow_mask, second.shadow_mask)
    assert setups[1] is setups[0] and setups[2] is not setups[0]
    assert not np.array_equal(setups[2].maps[0].matrix, setups[0].maps[0].matrix)


def _render_under_a_sky(engine, scene, **render_kw) -> list:
    """The watched renders (with "covered") of ``bpy.ops.render.render(**render_kw)`` under a sky of (0.2, 0.3, 0.4)
    (its Background node's colour, the world Cycles renders in 4.2 and 5.0)."""
    scene.world = sky_world("lixel_test sky", (0.2, 0.3, 0.4))
    try:
        with engine.watch_renders(read={"covered", "shadow_mask", "combined"}) as got:
            assert bpy.ops.render.render(scene=scene.name, **render_kw) == {"FINISHED"}
    finally:
        bpy.data.worlds.remove(scene.world)
    return got


def _render_frames_1_to_3_hiding_on_2(engine, scene, objects, tmp_path) -> list:
    """Frames 1..3 rendered as an animation under that sky, ``objects`` keyed hidden from renders on frame 2; all
    three files written."""
    for ob in objects:
        for frame, hidden in ((1, False), (2, True), (3, False)):
            ob.hide_render = hidden
            ob.keyframe_insert("hide_render", frame=frame)
    scene.frame_start, scene.frame_end = 1, 3
    scene.render.filepath = str(tmp_path / "frame_")
    scene.render.image_settings.file_format = "PNG"
    got = _render_under_a_sky(engine, scene, animation=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frame_0001.png", "frame_0002.png", "frame_0003.png"]
    return got


def _lit_by_the_world_alone(result, world):
    """No direct light and no shadow: each surface the camera sees is the world colour times the albedo (0.8,
    Blender's default grey), the rest the world colour."""
    covered = result.covered
    assert covered.mean() > 0.3 and not result.shadow_mask.any()
    expected = np.where(covered[..., None], [*(0.8 * np.asarray(world)), 1.0], [*world, 1.0])
    np.testing.assert_allclose(result.combined, expected, rtol=1e-5)


def test_a_scene_with_no_light_is_lit_by_the_world_alone(engine, scene, capfd):
    """Blender's engines light a scene with no light by its world; Lixel refused it ("has no light"). The panel and
    operators still say so (test_audit_catalogue); a render shows the world's light with that warning."""
    build(scene, with_light=False)
    got = _render_under_a_sky(engine, scene)
    assert "Traceback" not in capfd.readouterr().err
    _lit_by_the_world_alone(got[-1]["result"], (0.2, 0.3, 0.4))
    assert got[-1]["warnings"] == (f"Lixel: no shadows in this view (Scene '{scene.name}' has no light: add a Sun, "
                                   f"Point, Spot or Area light (Add > Light); the frame is lit by the world alone)",)


def test_a_light_keyed_hidden_for_a_frame_leaves_it_lit_by_the_world_and_the_animation_goes_on(engine, scene,
                                                                                              tmp_path):
    """The only light keyed hidden from renders on frame 2 (a blackout): Blender's engines light that frame by the
    world alone. Lixel refused it ("has no light"), which ended an animation render there: frames 2 and 3 of 3 were
    never written. Frame 2 now shows the world's light, unshadowed, with a warning, and the animation goes on."""
    build(scene)
    got = _render_frames_1_to_3_hiding_on_2(engine, scene, [scene.objects["Sun"]], tmp_path)
    first, dark, last = (g["result"] for g in got)
    _lit_by_the_world_alone(dark, (0.2, 0.3, 0.4))
    assert last.shadow_mask.max() > 0.5 and (last.combined[..., :3] > dark.combined[..., :3] + 0.1).any()
    np.testing.assert_array_equal(first.combined, last.combined)
    assert got[1]["warnings"] == (f"Lixel: no shadows in this view (Scene '{scene.name}' has no light: add a Sun, "
                                  f"Point, Spot or Area light (Add > Light); the frame is lit by the world alone)",)


def test_a_frame_with_nothing_visible_shows_the_world_and_the_animation_goes_on(engine, scene, tmp_path):
    """Objects keyed hidden from renders for a frame (a cut, a title): Blender's engines render the world there.
    Lixel refused the frame ("no visible mesh, curve or text objects"), which ended an animation render at it: frames 2 and 3 of 3 were
    never written. It now renders the world background with a warning, and the animation goes on."""
    build(scene)
    got = _render_frames_1_to_3_hiding_on_2(engine, scene, [scene.objects["Ground"], scene.objects["Box"]], tmp_path)
    first, empty, last = (g["result"] for g in got)
    np.testing.assert_allclose(empty.combined.reshape(-1, 4), [[0.2, 0.3, 0.4, 1.0]] * empty.combined[..., 0].size,
                               rtol=1e-6)
    assert not empty.shadow_mask.any() and last.shadow_mask.max() > 0.5
    np.testing.assert_array_equal(first.combined, last.combined)
    assert got[1]["warnings"] == ("Lixel: no shadows in this view (scene '" + scene.name + "' has no visible faces "
                                  "(no mesh, curve or text object with faces), so the frame shows only the world background)",)


def test_a_lixel_light_hidden_from_renders_is_named_and_lights_nothing(engine, scene, capfd):
    """Blender's engines light nothing with a light hidden from renders (the viewport still shows it): the render
    shows the world's light alone and names the light (it was refused, ending an animation render)."""
    build(scene)
    scene.lixel.light = sun = scene.objects["Sun"]
    sun.hide_render = True
    got = _render_under_a_sky(engine, scene)
    assert "Traceback" not in capfd.readouterr().err
    _lit_by_the_world_alone(got[-1]["result"], (0.2, 0.3, 0.4))
    assert re.fullmatch(r"Lixel: no shadows in this view \(The Lixel light 'Sun' is not among the lights scene "
                        r"'lixel_test[.\d]*' shows \(hidden, in an excluded collection or in another scene\).*; the "
                        r"frame is lit by the world alone\)", got[-1]["warnings"][0])
    sun.hide_render = False
    with engine.watch_renders() as got:
        assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    assert got[-1]["result"].shadow_mask.max() > 0.5 and not got[-1]["warnings"]


def test_a_lixel_light_a_script_set_to_another_object_is_named_as_no_light(engine, scene, capfd, lixel):
    """The panel's Light takes lights only, but a script's ``scene.lixel.light = ob`` passes any object: F12 and
    Refresh said the mesh "is not among the lights scene shows (hidden, in an excluded collection or in another
    scene): show it" -- it was shown. They name it as what it is, and what to do."""
    build(scene)
    scene.lixel.light = scene.objects["Box"]
    got = _render_under_a_sky(engine, scene)
    assert "Traceback" not in capfd.readouterr().err
    _lit_by_the_world_alone(got[-1]["result"], (0.2, 0.3, 0.4))
    said = "The Lixel light 'Box' is a mesh, not a light: choose a light (Lixel panel > Light)"
    assert got[-1]["warnings"][0] == f"Lixel: no shadows in this view ({said}; the frame is lit by the world alone)"
    with bpy.context.temp_override(scene=scene), pytest.raises(RuntimeError, match=re.escape(said)):
        bpy.ops.lixel.refresh()


def _differing(a, b) -> float:
    return float((np.abs(a - b).max(axis=-1) > 1e-3).mean())


@pytest.mark.parametrize("camera_type, fit", [("PERSP", "AUTO"), ("PERSP", "VERTICAL"), ("ORTHO", "AUTO")])
def test_each_stereo_eye_is_rendered_from_its_own_camera(engine, scene, tmp_path, camera_type, fit):
    """Output properties > Stereoscopy > Stereo 3D: each eye is Blender's (``camera_model_matrix``,
    ``camera_shift_x``). With the pivot at the centre and Off-Axis convergence, an eye is the camera moved half the
    interocular distance along its X and shifted by (interocular / sensor width) (lens / convergence) / 2 towards
    the other eye: each eye equals a plain render from a camera placed so, and both files are written. (Before, the
    left eye came out empty; then stereo was refused.)"""
    build(scene)
    cam = scene.camera
    cam.data.type, cam.data.ortho_scale, cam.data.sensor_fit, cam.data.shift_x = camera_type, 9.0, fit, 0.1
    st = cam.data.stereo
    st.interocular_distance, st.convergence_distance, st.convergence_mode, st.pivot = 1.0, 8.0, "OFFAXIS", "CENTER"
    r = scene.render
    r.use_multiview, r.views_format, r.image_settings.views_format = True, "STEREO_3D", "INDIVIDUAL"
    r.filepath = str(tmp_path / "eye_.png")
    with engine.watch_renders() as got:
        assert bpy.ops.render.render(scene=scene.name, write_still=True) == {"FINISHED"}
    eyes = {g["view"]: g["result"].combined for g in got}
    assert sorted(eyes) == ["left", "right"] and _differing(eyes["left"], eyes["right"]) > 0.01
    assert (tmp_path / "eye__L.png").exists() and (tmp_path / "eye__R.png").exists()
    r.use_multiview = False
    for side, sign in (("left", 1), ("right", -1)):
        eye = add(scene, f"Eye {side}", cam.data.copy())
        eye.matrix_world = cam.matrix_world @ Matrix.Translation((-sign * 0.5, 0, 0))
        eye.data.shift_x = 0.1 + sign * (1.0 / cam.data.sensor_width) * (cam.data.lens / 8.0) / 2
        scene.camera = eye
        with engine.watch_renders() as plain:
            assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
        assert _differing(plain[-1]["result"].combined, eyes[side]) < 0.001   # (a pixel's float rounding)


def test_a_stereo_render_says_each_warning_once(engine, scene, capfd):
    build(scene)
    scene.objects["Sun"].data.energy = 0.0
    scene.render.use_multiview, scene.render.views_format = True, "STEREO_3D"
    capfd.readouterr()
    with engine.watch_renders() as got:
        assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    out = capfd.readouterr()
    assert len(got) == 2 and all("has a strength of 0" in g["warnings"][0] for g in got)
    assert (out.out + out.err).count("has a strength of 0") == 1


def test_multiview_renders_each_view_with_its_own_camera(engine, scene):
    """Stereoscopy > Multi-View: each view renders the scene camera's name with its suffix (Cam_L, Cam_R)."""
    build(scene)
    scene.camera.name = "Cam_L"
    right = add(scene, "Cam_R", scene.camera.data)
    right.location = (3, -6, 6)
    right.rotation_euler = (Vector((0, 0, 0)) - right.location).to_track_quat("-Z", "Y").to_euler()
    scene.render.use_multiview, scene.render.views_format = True, "MULTIVIEW"
    with engine.watch_renders() as got:
        assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    views = {g["view"]: g["result"].combined for g in got}
    scene.render.use_multiview = False
    for view, cam in (("left", "Cam_L"), ("right", "Cam_R")):
        scene.camera = scene.objects[cam]
        with engine.watch_renders() as plain:
            assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
        np.testing.assert_array_equal(plain[-1]["result"].combined, views[view])


def test_no_gpu_context_is_reported(engine, scene, capfd, monkeypatch, lixel):
    build(scene)
    ctx = importlib.import_module(lixel.__name__ + ".addon.gpu.context")

    def no_gpu():
        raise ctx.GPUUnavailableError("Lixel could not get a GPU context: test")

    monkeypatch.setattr(ctx, "ensure_gpu_context", no_gpu)
    with pytest.raises(RuntimeError, match="could not get a GPU context"):
        bpy.ops.render.render(scene=scene.name)
    assert "Traceback" not in capfd.readouterr().err


def test_nothing_of_a_render_outlives_it(engine, scene):
    """The result (maps at full resolution, the images) is freed when the render
    ends: only a watcher's own list holds it, and once that is dropped nothing does."""
    import gc
    import weakref
    build(scene)
    with engine.watch_renders() as got:
        assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    res = got[0]["result"]
    arrays = [res.combined, res.shadow_mask]
    refs = [weakref.ref(a) for a in arrays]
    del got, res, arrays
    gc.collect()
    assert [r() is None for r in refs] == [True] * len(refs)
    # and a render nobody watches leaves nothing behind either
    assert not hasattr(engine, "last_render") and engine._watchers == []


def test_engine_is_registered_with_gpu_context(engine):
    cls = bpy.types.RenderEngine.bl_rna_get_subclass_py("LIXEL")
    assert cls is not None and cls.bl_use_gpu_context
    assert "LIXEL" in bpy.types.RENDER_PT_format.COMPAT_ENGINES


SUBPROCESS = r'''
import importlib, importlib.util, sys
import bpy
conftest, blend, scene_name = sys.argv[1:4]
spec = importlib.util.spec_from_file_location("bconf", conftest)
bconf = importlib.util.module_from_spec(spec)
spec.loader.exec_module(bconf)
bpy.ops.wm.open_mainfile(filepath=blend)
bconf.enable_lixel()
scene = bpy.data.scenes[scene_name]
scene.render.engine = "LIXEL"                                   # -E LIXEL
scene.frame_set(1)                                              # -f 1
engine = importlib.import_module(bconf.ADDON_MODULE + ".addon.render.engine")
with engine.watch_renders() as got:
    bpy.ops.render.render(write_still=True, scene=scene.name)
last = got[-1]
print("LIXEL_RENDERED", last["scene"], float(last["result"].shadow_mask.mean()))
bconf.disable_lixel()
'''


def test_saved_file_renders_in_a_fresh_process(engine, scene, tmp_path, load_pixels):
    """What ``blender -b file.blend -E LIXEL -f 1`` does: open the file in a new
    process, pick the engine, render frame 1 and write it."""
    import os
    import subprocess
    import sys
    build(scene)
    blend = tmp_path / "scene.blend"
    out = tmp_path / "frame.png"
    scene.render.filepath = str(out)
    scene.render.image_settings.file_format = "PNG"
    scene.render.engine = "BLENDER_WORKBENCH"    # the engine comes from the command line
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    script = tmp_path / "render.py"
    script.write_text(SUBPROCESS)
    conftest = Path(__file__).with_name("conftest.py")
    proc = subprocess.run([sys.executable, str(script), str(conftest), str(blend), scene.name],
                          capture_output=True, text=True, timeout=300, env=dict(os.environ))
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr, proc.stderr[-2000:]
    marker = [line.split() for line in proc.stdout.splitlines() if line.startswith("LIXEL_RENDERED")]
    assert marker and marker[0][1] == scene.name and float(marker[0][2]) > 0.01
    assert out.exists()
    px = load_pixels(out)
    assert px.shape[:2] == (64, 96)
    assert px[..., :3].std() > 0.01  # an image, with shading and shadow


def test_a_view_with_nothing_to_shadow_renders_with_a_warning(engine, scene, capfd):
    build(scene)
    cam = scene.camera
    cam.rotation_euler = (0.0, math.pi, 0.0)  # straight up at the sky
    cam.location = (0, 0, 10)
    with engine.watch_renders(read={"covered"}) as got:
        assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    res = got[-1]["result"]
    assert not res.covered.any() and not res.shadow_mask.any()
    captured = capfd.readouterr()
    assert "no shadows in this view" in captured.err + captured.out
    np.testing.assert_allclose(res.combined[..., :3], np.broadcast_to(
        np.array(scene.world.color if scene.world else (0, 0, 0), dtype=np.float32), (64, 96, 3)), atol=1e-6)


def test_a_spot_lighting_nothing_visible_renders_ambient_only(engine, scene, capfd):
    build(scene, with_light=False)
    spot = add(scene, "Spot", bpy.data.lights.new("Spot", "SPOT"))
    spot.location = (0, 0, 5)
    spot.rotation_euler = (0.0, math.pi, 0.0)  # pointing up, away from everything
    with engine.watch_renders(read={"covered"}) as got:
        assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    res = got[-1]["result"]
    covered = res.covered
    assert covered.any() and not res.shadow_mask.any()
    ambient = np.array(scene.world.color if scene.world else (0, 0, 0), dtype=np.float32) * 0.8
    np.testing.assert_allclose(res.combined[covered][:, :3], np.broadcast_to(ambient, (covered.sum(), 3)),
                               atol=1e-6)
    captured = capfd.readouterr()
    assert "no shadows in this view" in captured.err + captured.out


def test_the_viewport_and_the_engine_share_one_scene_cache(engine, scene, lixel):
    """The live state (panel, overlays) reads the scene through the cache the
    engine renders from: the same bounds object, so one culling index."""
    live = importlib.import_module(lixel.__name__ + ".addon.ui.live")
    geometry_mod = importlib.import_module(lixel.__name__ + ".addon.scene.geometry")
    build(scene)
    dg = scene.view_layers[0].depsgraph
    dg.update()
    st = live.update(scene, dg)
    assert st.setup is not None, st.error
    again = live.update(scene, dg, changed={"bounds"})
    geometry = geometry_mod.shared_cache().update(dg, exclude=engine.is_debug_object)
    assert again.bounds is st.bounds is geometry.instances.bounds
    importlib.import_module(lixel.__name__ + ".addon.gpu.context").ensure_gpu_context()
    engine.render_depsgraph(dg)
    assert geometry_mod.shared_cache().update(dg, exclude=engine.is_debug_object).instances.bounds is st.bounds


def test_the_reports_frame_says_which_face_each_pixel_shows(engine, scene, lixel):
    """The report judges a frame as bench.rendered_error does: its frame carries the face normal of every pixel
    (NaN off the surfaces), so ``comparable_mask`` leaves out the crease pixels where the rasterizer and the ray
    caster saw one point of a box on two faces."""
    from bench.report.lixel import frame, report_settings
    build(scene)
    importlib.import_module(lixel.__name__ + ".addon.gpu.context").ensure_gpu_context()
    dg = scene.view_layers[0].depsgraph
    dg.update()
    fr = frame(dg, report_settings("uniform", 512), (96, 64))
    assert fr.world_normal is not None and fr.world_normal.shape == fr.world_position.shape
    seen = fr.world_normal[fr.covered]
    assert len(seen) > 1000 and np.all(np.isnan(fr.world_normal[~fr.covered]))
    axes = np.abs(seen).max(axis=1)                  # the ground and the box's faces are axis-aligned
    assert np.all(axes > math.cos(1e-3))


def test_f12_in_a_3d_view_with_a_local_camera_renders_that_camera(engine, scene):
    """View sidebar > View > Local Camera: F12 there renders with that camera, not the scene's (Blender's
    ``camera_override``; Workbench, EEVEE and Cycles do so in 4.2 and 5.0). The 3D view of the module's own window
    stands in for the user's."""
    build(scene)
    side = add(scene, "Side", bpy.data.cameras.new("Side"))
    side.location = (7, 1, 5)
    side.rotation_euler = (Vector((0, 0, 0)) - side.location).to_track_quat("-Z", "Y").to_euler()
    win = bpy.context.window
    area = next(a for a in win.screen.areas if a.type == "VIEW_3D")
    space, region = area.spaces.active, next(r for r in area.regions if r.type == "WINDOW")
    was = space.use_local_camera, space.camera
    space.use_local_camera, space.camera = True, side
    try:
        with engine.watch_renders() as got, \
                bpy.context.temp_override(window=win, area=area, region=region, space_data=space):
            assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    finally:
        space.use_local_camera, space.camera = was
    assert scene.camera.name == "Cam"
    scene.camera = side
    with engine.watch_renders() as own:
        assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    np.testing.assert_array_equal(got[-1]["result"].combined, own[-1]["result"].combined)


@pytest.mark.parametrize("passes", ["shadow", "none", "blurred"])
def test_film_transparent_leaves_the_sky_transparent(engine, scene, passes):
    """Render properties > Film > Transparent: where no surface is seen the combined image is (0, 0, 0, 0), as
    Workbench, EEVEE and Cycles give it, for compositing over a plate; surfaces keep alpha 1 and their colour.
    With the Shadow pass (whose values share the colour target's alpha), without it, and with the eye blur."""
    build(scene)
    scene.camera.location = (0, -7, 1.5)                     # a grazing view: ground below, sky above
    scene.camera.rotation_euler = (Vector((0, 0, 1)) - scene.camera.location).to_track_quat("-Z", "Y").to_euler()
    scene.view_layers[0].lixel_passes.shadow = passes != "none"
    scene.lixel.eye_blur = 2.0 if passes == "blurred" else 0.0
    try:
        with engine.watch_renders(read={"covered"}) as got:
            for transparent in (False, True):
                scene.render.film_transparent = transparent
                assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    finally:
        scene.view_layers[0].lixel_passes.shadow = True
        scene.lixel.eye_blur = 0.0
    opaque, clear = (g["result"] for g in got)
    covered = clear.covered
    assert 0.2 < covered.mean() < 0.8
    np.testing.assert_array_equal(clear.combined[~covered], 0.0)
    np.testing.assert_array_equal(clear.combined[covered], opaque.combined[covered])
    np.testing.assert_array_equal(opaque.combined[..., 3], 1.0)
    if passes != "none":
        np.testing.assert_array_equal(clear.shadow_mask, opaque.shadow_mask)
        assert clear.shadow_mask.min() == 0.0 and clear.shadow_mask.max() > 0.5


@pytest.mark.parametrize("transparent", [False, True])
@pytest.mark.parametrize("width,height,percent", [(96, 64, 2), (100, 100, 2), (96, 64, 100)])
def test_the_shadow_pass_is_the_shadow_at_any_size(engine, scene, width, height, percent, transparent):
    """A 1x1-pixel render (96x64 at 2 %, a thumbnail or a test render) gave a Shadow pass of 1 on a lit pixel: the
    pass and the combined image's alpha share the colour target's alpha channel, and at one pixel the pass was a view
    of the alpha that the combined image's alpha 1 then overwrote. The pass is the shading's shadow at every size."""
    build(scene)
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = width, height, percent
    scene.render.film_transparent = transparent
    scene.lixel.eye_blur = 0.0
    with engine.watch_renders(read={"covered", "shadow_raw"}) as got:
        assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    res = got[-1]["result"]
    assert res.shadow_mask.shape == (height * percent // 100, width * percent // 100) and res.covered.all()
    np.testing.assert_array_equal(res.shadow_mask, res.shadow_raw)
    np.testing.assert_array_equal(res.combined[..., 3], 1.0)
    if percent == 100:
        assert res.shadow_mask.max() > 0.5 and res.shadow_mask.min() == 0.0


def _exr_channels(path) -> dict:
    """{channel name: (H, W) float32} of an uncompressed 32-bit float scan-line OpenEXR file, single- or multi-part
    (Blender's multilayer files; bpy cannot read them back per layer). Layout (openexr.com, "OpenEXR File
    Layout"): magic and version (bit 12: multi-part), each part's header (attributes: name, type, size, value; up to
    an empty name), then each part's offsets of its scan lines, each line its part (multi-part), y, size and each
    channel's row in the header's order."""
    import struct
    data = Path(path).read_bytes()
    multi = bool(struct.unpack_from("<i", data, 4)[0] & 0x1000)
    at, parts = 8, []
    while True:
        header = {}
        while data[at]:
            name, at = data[at:data.index(b"\0", at)].decode(), data.index(b"\0", at) + 1
            at = data.index(b"\0", at) + 1
            size, = struct.unpack_from("<i", data, at)
            header[name], at = data[at + 4:at + 4 + size], at + 4 + size
        parts.append(header)
        at += 1
        if not multi or not data[at]:
            break
    at += multi
    out = {}
    for header in parts:
        channels, c = [], header["channels"]
        while c[0]:
            channels.append(c[:c.index(b"\0")].decode())
            c = c[c.index(b"\0") + 1:]
            assert struct.unpack_from("<i", c)[0] == 2 and header["compression"] == b"\0", "FLOAT, uncompressed"
            c = c[16:]
        x0, y0, x1, y1 = struct.unpack("<4i", header["dataWindow"])
        w, h = x1 - x0 + 1, y1 - y0 + 1
        offsets = struct.unpack_from(f"<{h}Q", data, at)
        at += 8 * h
        rows = np.stack([np.frombuffer(data, "<f4", w * len(channels), o + 8 + 4 * multi).reshape(len(channels), w)
                         for o in offsets])
        out.update({name: rows[::-1, i] for i, name in enumerate(channels)})   # row 0 at the bottom
    return out


def test_each_view_layer_gets_its_own_render(engine, scene, tmp_path):
    """Blender renders every view layer switched on for rendering, calling the engine once for each: each must go
    to its own layer of the result (a multilayer EXR for compositing). Before, every layer's image went to the
    first layer, the last overwriting it, and the others stayed black."""
    build(scene)
    boxes = bpy.data.collections.new("Boxes")
    scene.collection.children.link(boxes)
    boxes.objects.link(scene.objects["Box"])
    scene.collection.objects.unlink(scene.objects["Box"])
    scene.view_layers.new("No Box").layer_collection.children["Boxes"].exclude = True
    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):           # 5.0
        settings.media_type = "MULTI_LAYER_IMAGE"
    else:
        settings.file_format = "OPEN_EXR_MULTILAYER"
    settings.color_depth, settings.exr_codec = "32", "NONE"
    scene.render.filepath = str(tmp_path / "layers.exr")
    with engine.watch_renders() as got:
        assert bpy.ops.render.render(scene=scene.name, write_still=True) == {"FINISHED"}
    assert [g["result"].counts.casters_drawn for g in got] == [2, 1]
    layers = _exr_channels(tmp_path / "layers.exr")
    first = scene.view_layers[0].name
    for name, g in zip((first, "No Box"), got):
        np.testing.assert_allclose(layers[f"{name}.Combined.G"], g["result"].combined[..., 1], rtol=1e-6)
        np.testing.assert_array_equal(layers[f"{name}.Shadow.X"], g["result"].shadow_mask)
    assert layers[f"{first}.Shadow.X"].max() > 0.5 and layers["No Box.Shadow.X"].max() == 0.0


def test_a_light_with_shadow_off_casts_none_as_in_blenders_engines(engine, scene, capfd):
    """Light properties > Shadow off: EEVEE and Cycles light the scene with it but cast no shadow. Lixel did
    shadow it; it now renders it unshadowed and says why."""
    build(scene)
    sun = scene.objects["Sun"]
    with engine.watch_renders() as got:
        for use_shadow in (False, True):
            sun.data.use_shadow = use_shadow
            assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    off, on = (g["result"] for g in got)
    assert not off.shadow_mask.any() and on.shadow_mask.mean() > 0.01
    lit = on.shadow_mask < 0.01
    np.testing.assert_allclose(off.combined[lit], on.combined[lit], atol=1e-6)
    assert (off.combined[~lit, :3] > on.combined[~lit, :3]).all()
    assert "light 'Sun' casts no shadows, as in Blender's engines: its Shadow is off" in got[0]["warnings"][0]


@pytest.mark.parametrize("clip_start, start, lost", [(1e-3, "", None), (3e-6, "3 µm", "7.16 m"),
                                                     (1e-6, "1 µm", "4.56 m")])
def test_a_clip_start_too_small_for_what_is_seen_is_named(engine, scene, clip_start, start, lost):
    """Clip 1e-6 to 10 (a ratio Lixel accepts, below 2^24) rendered black with "the camera sees no shadow
    receiver": 32-bit depth loses everything beyond 4.56 m. The render now says which camera and what to raise."""
    build(scene)
    scene.camera.data.clip_start, scene.camera.data.clip_end = clip_start, 10.0
    with engine.watch_renders() as got:
        assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    notes = [w for w in got[-1]["warnings"] if "32-bit depth" in w]
    assert notes == ([] if lost is None else [
        f"Lixel: Camera 'Cam' clips from {start} to 10 m: 32-bit depth cannot tell its clip end from surfaces farther "
        f"away than {lost}, so they render as background; raise the clip start (Camera properties > Lens > Clip)"])


def test_a_linked_lixel_light_is_read_itself_not_a_local_light_of_its_name(engine, scene, tmp_path):
    """A lighting rig linked from a library may hold a "Sun" while the file has its own "Sun". The engine looked
    the Lixel light up by name and took the local one's settings: here its Shadow off, so no shadow at all."""
    build(scene)
    local = scene.objects["Sun"]
    local.name = "Local"
    rig = bpy.data.objects.new("Sun", bpy.data.lights.new("Rig Sun", "SUN"))
    rig.rotation_euler = local.rotation_euler
    bpy.data.libraries.write(str(tmp_path / "rig.blend"), {rig})
    data = rig.data
    bpy.data.objects.remove(rig)
    bpy.data.lights.remove(data)
    local.name = "Sun"
    with bpy.data.libraries.load(str(tmp_path / "rig.blend"), link=True) as (_src, dst):
        dst.objects = ["Sun"]
    linked = dst.objects[0]
    try:
        scene.collection.objects.link(linked)
        local.data.use_shadow, local.data.energy = False, 0.0
        assert linked.name == local.name == "Sun" and linked.library is not None
        scene.lixel.light = linked
        with engine.watch_renders() as got:
            assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
        assert got[-1]["result"].shadow_mask.mean() > 0.01
        assert not any("Shadow is off" in w or "strength of 0" in w for w in got[-1]["warnings"])
    finally:
        scene.lixel.light = None
        library = linked.library
        bpy.data.objects.remove(linked)
        bpy.data.libraries.remove(library)


@pytest.mark.parametrize("chosen", [False, True])
def test_a_light_in_an_instanced_collection_lights_from_its_instance(engine, scene, chosen):
    """File > Link of a collection (a lighting rig) makes a collection instance: its sun lights the scene in
    EEVEE and Cycles, from the instance's transform. Lixel said "has no light" (or refused it as the chosen light);
    it now shadows as from the same sun placed at the instance's world transform."""
    build(scene)
    sun = scene.objects["Sun"]
    with engine.watch_renders() as direct:
        sun.rotation_euler = (math.radians(20), 0, math.radians(-30))
        assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    rig = bpy.data.collections.new("Rig")
    rig.objects.link(sun)
    scene.collection.objects.unlink(sun)
    sun.rotation_euler = (math.radians(20), 0, 0)                     # Euler XYZ: Z(-30°) after X(20°)
    instance = add(scene, "Rig instance", None)
    instance.instance_type, instance.instance_collection = "COLLECTION", rig
    instance.rotation_euler = (0, 0, math.radians(-30))
    instance.location = (3, 2, 1)                                     # a sun: only its direction matters
    scene.lixel.light = sun if chosen else None
    try:
        with engine.watch_renders() as got:
            assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    finally:
        scene.lixel.light = None
        bpy.data.collections.remove(rig)
        light = sun.data
        bpy.data.objects.remove(sun)                                  # no longer in the scene: not the fixture's
        bpy.data.lights.remove(light)
    assert got and got[-1]["result"].shadow_mask.mean() > 0.01
    np.testing.assert_allclose(got[-1]["result"].combined, direct[-1]["result"].combined, atol=1e-4)


def _add_hold(scene, location=(0.4, -2.2, 1.6), size=0.9):
    """A cube between the camera and the box of :func:`build` (it hides part of the box and shadows the ground)."""
    hold = add(scene, "Hold", cube_mesh("Hold", size, 0.0))
    hold.location = location
    return hold


def _inside(world_position, ob, margin=1e-3) -> np.ndarray:
    """Pixels whose surface seen lies in ``ob``'s world bounding box."""
    corners = np.array([ob.matrix_world @ Vector(c) for c in ob.bound_box])
    lo, hi = corners.min(axis=0) - margin, corners.max(axis=0) + margin
    return np.all((world_position >= lo) & (world_position <= hi), axis=-1)


def _render(engine, scene, read=()):
    with engine.watch_renders(read=set(read)) as got:
        assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    return got[-1]


@pytest.mark.parametrize("passes", ["shadow", "footprint", "blurred"])
@pytest.mark.parametrize("how", ["object", "collection"])
def test_a_holdout_leaves_a_transparent_hole_that_hides_what_is_behind_it(engine, scene, how, passes):
    """Object properties > Visibility > Holdout, or a collection's Holdout in the view layer: Cycles renders the
    held-out object as a hole, (0, 0, 0, 0), with Film Transparent on or off; the hole still hides what is behind it
    (here part of the box), the object still casts its shadow, and the other passes are empty there as where nothing
    is seen (measured with Cycles in 4.2.23 and 5.0.1). So does Lixel: with the Shadow pass (which shares the colour
    target's alpha), with the Footprint pass, and with the eye blur; every other pixel is the render without the
    holdout, bit for bit (with the eye blur, whose neighbourhoods leave the hole out, the pixels away from it).
    No warning is given: there is nothing to warn about."""
    build(scene)
    hold = _add_hold(scene)
    switches = scene.view_layers[0].lixel_passes
    switches.shadow, switches.footprint = passes != "footprint", passes == "footprint"
    scene.lixel.eye_blur = 2.0 if passes == "blurred" else 0.0
    held = bpy.data.collections.new("Held")
    layer = None
    try:
        plain = {}
        for transparent in (False, True):
            scene.render.film_transparent = transparent
            plain[transparent] = _render(engine, scene, read={"world_position"})
        hold.hide_render = True
        behind = _render(engine, scene, read={"world_position"})
        hold.hide_render = False
        if how == "object":
            hold.is_holdout = True
        else:
            scene.collection.children.link(held)
            scene.collection.objects.unlink(hold)
            held.objects.link(hold)
            scene.view_layers[0].update()                             # its layer collection, for the view layer
            layer = scene.view_layers[0].layer_collection.children[held.name]
            layer.holdout = True
        cut = {}
        for transparent in (False, True):
            scene.render.film_transparent = transparent
            cut[transparent] = _render(engine, scene, read={"covered"})
    finally:
        switches.shadow, switches.footprint = True, False
        scene.lixel.eye_blur = 0.0
        scene.render.film_transparent = False
        hold.is_holdout = False
        if layer is not None:
            layer.holdout = False
        for ob in list(held.objects):                                 # back in the scene, which the fixture clears
            held.objects.unlink(ob)
            scene.collection.objects.link(ob)
        bpy.data.collections.remove(held)
    hole = _inside(plain[False]["result"].world_position, hold)
    assert hole.sum() > 100
    hidden = _inside(behind["result"].world_position, scene.objects["Box"]) & hole
    assert hidden.sum() > 20, "the hole hides part of the box"
    away = ~hole
    if passes == "blurred":     # beyond the blur's reach of the hole (2 px at the nearest surface)
        for _ in range(3):
            away[1:] &= away[:-1]; away[:-1] &= away[1:]; away[:, 1:] &= away[:, :-1]; away[:, :-1] &= away[:, 1:]
    for transparent in (False, True):
        res, ref = cut[transparent]["result"], plain[transparent]["result"]
        assert not [w for w in cut[transparent]["warnings"] if "holdout" in w.lower()]
        np.testing.assert_array_equal(res.combined[hole], 0.0)
        assert not res.covered[hole].any()
        np.testing.assert_array_equal(res.combined[away], ref.combined[away])
        if passes == "footprint":
            np.testing.assert_array_equal(res.footprint_heatmap[hole], [[0.0, 0.0, 0.0, 1.0]] * int(hole.sum()))
            np.testing.assert_array_equal(res.footprint_heatmap[away], ref.footprint_heatmap[away])
        else:
            np.testing.assert_array_equal(res.shadow_mask[hole], 0.0)
            np.testing.assert_array_equal(res.shadow_mask[away], ref.shadow_mask[away])
    if passes == "shadow":      # its shadow on the ground: shadowed with it held out, lit with it hidden
        shade = cut[False]["result"].shadow_mask, behind["result"].shadow_mask
        assert ((shade[0] > 0.9) & (shade[1] < 0.1) & ~hole).sum() > 20


def _instancer(scene, kind: str, instanced):
    """An object of ``scene`` that instances ``instanced`` (an object of no scene) once at the :func:`_add_hold`
    spot: an empty instancing a collection, or a mesh whose geometry nodes put it on a point."""
    if kind == "collection":
        rig = bpy.data.collections.new("lixel_test rig")
        rig.objects.link(instanced)
        host = add(scene, "Instancer", None)
        host.instance_type, host.instance_collection = "COLLECTION", rig
    else:
        host = add(scene, "Instancer", cube_mesh("Instancer", 0.1, 0.0))
        tree = bpy.data.node_groups.new("lixel_test instances", "GeometryNodeTree")
        tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
        tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
        out = tree.nodes.new("NodeGroupOutput")
        points, on_points = tree.nodes.new("GeometryNodePoints"), tree.nodes.new("GeometryNodeInstanceOnPoints")
        info = tree.nodes.new("GeometryNodeObjectInfo")
        info.inputs["Object"].default_value, info.inputs["As Instance"].default_value = instanced, True
        tree.links.new(points.outputs[0], on_points.inputs["Points"])
        tree.links.new(info.outputs["Geometry"], on_points.inputs["Instance"])
        tree.links.new(on_points.outputs[0], out.inputs[0])
        host.modifiers.new("Instances", "NODES").node_group = tree
    host.location = (0.4, -2.2, 1.6)
    return host


def _remove_instancer(host, instanced) -> None:
    """Undo :func:`_instancer` (the host goes with the scene)."""
    if host.instance_type == "COLLECTION":
        bpy.data.collections.remove(host.instance_collection)
    else:
        tree = host.modifiers[0].node_group
        host.modifiers.clear()
        bpy.data.node_groups.remove(tree)
    mesh = instanced.data
    bpy.data.objects.remove(instanced)
    bpy.data.meshes.remove(mesh)


def _instanced_pixels(world_position) -> np.ndarray:
    """Pixels showing the 0.9 cube :func:`_instancer` places."""
    p = world_position
    return np.all((p >= np.array([-0.05, -2.65, 1.15]) - 1e-3) & (p <= np.array([0.85, -1.75, 2.05]) + 1e-3), axis=-1)


@pytest.mark.parametrize("held", ["instancer", "instanced object"])
@pytest.mark.parametrize("kind", ["collection", "nodes"])
def test_an_instance_is_held_out_with_its_instancer(engine, scene, kind, held):
    """Cycles holds an instance out when its instancer is held out: an empty instancing a collection, or an object
    whose geometry nodes make instances; the instanced object's own Holdout does not count (measured in 4.2.23 and
    5.0.1; EEVEE answers the other way round, see docs). Lixel follows Cycles, through both of its readers of
    instances (the walk, and in 4.3+ the array reader that geometry-nodes instances take)."""
    build(scene)
    instanced = bpy.data.objects.new("Hold", cube_mesh("Hold", 0.9, 0.0))
    host = _instancer(scene, kind, instanced)
    try:
        plain = _render(engine, scene, read={"world_position"})
        (host if held == "instancer" else instanced).is_holdout = True
        cut = _render(engine, scene, read={"covered"})
    finally:
        instanced.is_holdout = host.is_holdout = False
        _remove_instancer(host, instanced)
    hole = _instanced_pixels(plain["result"].world_position)
    assert hole.sum() > 100
    res = cut["result"]
    if held == "instancer":
        np.testing.assert_array_equal(res.combined[hole], 0.0)
        np.testing.assert_array_equal(res.combined[~hole], plain["result"].combined[~hole])
    else:
        np.testing.assert_array_equal(res.combined, plain["result"].combined)
        assert res.covered.all()


def test_a_holdout_out_of_view_changes_no_pixel(engine, scene):
    """A scene whose held-out objects the camera does not see renders bit for bit as without them held out, every
    pass (the frame draws and shades exactly as before holdouts were supported; checked against main's engine on
    the forest and chess scenes too, docs/architecture.md "Holdouts"): only a held-out surface in view changes the frame."""
    build(scene)
    hold = _add_hold(scene, location=(0.0, -12.0, 9.0))               # behind the camera
    scene.view_layers[0].lixel_passes.footprint = True
    try:
        plain = _render(engine, scene, read={"covered"})
        hold.is_holdout = True
        cut = _render(engine, scene, read={"covered"})
    finally:
        scene.view_layers[0].lixel_passes.footprint = False
    for image in ("combined", "shadow_mask", "footprint_heatmap", "covered"):
        np.testing.assert_array_equal(getattr(cut["result"], image), getattr(plain["result"], image))


def test_the_viewport_picture_shows_a_holdout_as_a_hole(engine, scene, lixel):
    """The engine draws no viewport of its own (no ``view_draw``): the 3D view shows Lixel's shadowed camera view as
    a picture (Lixel panel > Shadowed scene, ``addon.ui.renders.pip_textures``), which draws through the same frame
    as F12, so a holdout is a hole there too, black in the picture as in a render shown without alpha."""
    live = importlib.import_module(lixel.__name__ + ".addon.ui.live")
    renders = importlib.import_module(lixel.__name__ + ".addon.ui.renders")
    describe = importlib.import_module(lixel.__name__ + ".addon.scene.describe")
    build(scene)
    hold = _add_hold(scene)
    scene.lixel.eye_blur = 0.0

    def picture():
        dg = describe.evaluated_depsgraph(scene)
        return renders.pip_images(live.update(scene, dg), dg, 96, False, True)["scene"]
    plain = picture()
    hold.is_holdout = True
    cut = picture()
    changed = np.any(cut != plain, axis=-1)
    assert changed.sum() > 100
    np.testing.assert_array_equal(cut[changed], 0.0)


def _link(scene, attr: str, states: dict, child: dict = ()):
    """A collection set as the Sun's ``attr`` ("receiver_collection": Light Linking, "blocker_collection": Shadow
    Linking) holding the objects of ``states`` ({object: "INCLUDE" | "EXCLUDE"}) and a child collection per entry
    of ``child`` ({state: [objects]})."""
    coll = bpy.data.collections.new("lixel_test linking")
    for ob, state in states.items():
        coll.objects.link(ob)
        coll.collection_objects[len(coll.objects) - 1].light_linking.link_state = state
    for state, obs in dict(child).items():
        sub = bpy.data.collections.new(f"lixel_test linking {state.lower()}")
        coll.children.link(sub)
        for ob in obs:
            sub.objects.link(ob)
        coll.collection_children[len(coll.children) - 1].light_linking.link_state = state
    setattr(scene.objects["Sun"].light_linking, attr, coll)
    return coll


def _unlink(coll) -> None:
    for sub in list(coll.children):
        bpy.data.collections.remove(sub)
    bpy.data.collections.remove(coll)


def _with_and_without(engine, scene, attr: str, states: dict, child: dict = ()) -> tuple:
    """(render without linking, render with :func:`_link`'s collection), reading the combined image, the shadow
    and the surface seen."""
    plain = _render(engine, scene, read={"combined", "shadow_mask", "world_position"})
    coll = _link(scene, attr, states, child)
    try:
        return plain, _render(engine, scene, read={"combined", "shadow_mask", "world_position"})
    finally:
        _unlink(coll)


def _world_lit(res) -> float:
    """The combined image's value where the sun's light is fully shadowed (the world's light alone)."""
    shadowed = res.combined[res.shadow_mask >= 1.0][:, :3]
    assert len(shadowed) > 20 and np.ptp(shadowed, axis=0).max() == 0.0
    return shadowed[0]


@pytest.mark.parametrize("passes", ["shadow", "blurred"])
def test_an_object_excluded_from_the_lights_receivers_is_not_lit_by_it_but_still_casts_its_shadow(
        engine, scene, passes):
    """Light Linking (Object properties > Shading) with only Excluded objects: Cycles lights every object but
    those; an excluded object gets the world's light alone, still hides what is behind it and still casts the
    light's shadow (measured in 4.2.23 and 5.0.1). So does Lixel, with no shadow of that light on it in the Shadow
    pass (it gets none of its light to shadow); every other pixel is the render without linking, bit for bit (with
    the eye blur, the pixels beyond its reach of the object). No warning: Lixel does what Cycles does."""
    build(scene)
    world_lit = _world_lit(_render(engine, scene, read={"combined", "shadow_mask"})["result"])
    scene.lixel.eye_blur = 2.0 if passes == "blurred" else 0.0
    box = scene.objects["Box"]
    try:
        plain, linked = _with_and_without(engine, scene, "receiver_collection", {box: "EXCLUDE"})
    finally:
        scene.lixel.eye_blur = 0.0
    res, ref = linked["result"], plain["result"]
    seen = _inside(ref.world_position, box)
    assert seen.sum() > 100
    np.testing.assert_array_equal(_inside(res.world_position, box), seen)      # it still hides what is behind it
    assert not [w for w in linked["warnings"] if "Linking" in w]
    away = ~seen
    if passes == "blurred":     # beyond the blur's reach of it (2 px at the nearest surface)
        for _ in range(3):
            away[1:] &= away[:-1]; away[:-1] &= away[1:]; away[:, 1:] &= away[:, :-1]; away[:, :-1] &= away[:, 1:]
    np.testing.assert_array_equal(res.combined[away], ref.combined[away])      # its shadow on the ground, kept
    np.testing.assert_array_equal(res.shadow_mask[away], ref.shadow_mask[away])
    if passes == "shadow":
        assert (ref.shadow_mask[away] > 0.9).sum() > 100
    np.testing.assert_array_equal(res.shadow_mask[seen], 0.0)
    np.testing.assert_allclose(res.combined[seen][:, :3], np.broadcast_to(world_lit, (seen.sum(), 3)),
                               atol=1e-6 if passes == "blurred" else 0.0)
    assert (ref.combined[seen][:, :3] > world_lit + 0.05).all(axis=-1).sum() > 50, "lit without linking"


def test_a_blocker_excluded_from_shadow_linking_casts_no_shadow_of_that_light(engine, scene):
    """Shadow Linking with only Excluded objects: Cycles lets every object but those cast the light's shadow; an
    excluded object is still lit as before (measured in 4.2.23 and 5.0.1). So does Lixel: the light's maps leave it
    out. (Here it is the only caster: no shadow is left.)"""
    build(scene)
    box = scene.objects["Box"]
    plain, linked = _with_and_without(engine, scene, "blocker_collection", {box: "EXCLUDE"})
    res, ref = linked["result"], plain["result"]
    assert (ref.shadow_mask > 0.9).sum() > 100
    assert res.shadow_mask.max() < 0.01
    assert res.counts.casters_drawn < ref.counts.casters_drawn
    seen = _inside(ref.world_position, box)
    np.testing.assert_allclose(res.combined[seen], ref.combined[seen], atol=1e-6)   # lit as before
    assert not [w for w in linked["warnings"] if "Linking" in w]


@pytest.mark.parametrize("how", ["object", "child collection"])
@pytest.mark.parametrize("attr", ["receiver_collection", "blocker_collection"])
def test_with_an_include_only_the_included_objects_are_lit_or_cast(engine, scene, attr, how):
    """With any Included entry, Cycles lights (Light Linking) or lets cast (Shadow Linking) only the Included
    objects, whatever else is Excluded; a child collection's state is its objects' (measured in 4.2.23 and 5.0.1).
    Light Linking with the box Included and the ground Excluded lights the box alone (the ground gets the world's
    light, and no shadow in the Shadow pass); Shadow Linking with the ground alone Included leaves the box out: no
    shadow is cast."""
    build(scene)
    box, ground = scene.objects["Box"], scene.objects["Ground"]
    included, excluded = (box, {ground: "EXCLUDE"}) if attr == "receiver_collection" else (ground, {})
    if how == "object":
        plain, linked = _with_and_without(engine, scene, attr, {included: "INCLUDE", **excluded})
    else:
        plain, linked = _with_and_without(engine, scene, attr, excluded, child={"INCLUDE": [included]})
    res, ref = linked["result"], plain["result"]
    if attr == "blocker_collection":
        assert (ref.shadow_mask > 0.9).sum() > 100
        assert res.shadow_mask.max() < 0.01
        return
    on_box = _inside(ref.world_position, box)
    on_ground = ~on_box & res.covered if res.covered is not None else ~on_box & (ref.world_position[..., 2] < 1e-3)
    on_ground &= np.abs(ref.world_position[..., 2]) < 1e-3
    assert on_ground.sum() > 500
    np.testing.assert_array_equal(res.combined[on_box], ref.combined[on_box])
    np.testing.assert_array_equal(res.shadow_mask[on_ground], 0.0)
    np.testing.assert_array_equal(res.combined[on_ground][:, :3],
                                  np.broadcast_to(_world_lit(ref), (on_ground.sum(), 3)))


def test_the_linking_of_an_instanced_light_is_named_not_silently_ignored(engine, scene):
    """A light that is itself an instance (of a collection instance: a linked lighting rig) is the one case whose
    linking Lixel does not follow (its readers look for linking on the scene's light objects only): it lights and
    shadows every object, and says so, naming the light, the collection and what to do."""
    build(scene)
    sun = scene.objects["Sun"]
    rig = bpy.data.collections.new("Rig")
    rig.objects.link(sun)
    scene.collection.objects.unlink(sun)
    instance = add(scene, "Rig instance", None)
    instance.instance_type, instance.instance_collection = "COLLECTION", rig
    coll = bpy.data.collections.new("lixel_test linking")
    coll.objects.link(scene.objects["Box"])
    coll.collection_objects[0].light_linking.link_state = "EXCLUDE"
    sun.light_linking.blocker_collection = coll
    try:
        with engine.watch_renders() as got:
            assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    finally:
        bpy.data.collections.remove(coll)
        bpy.data.collections.remove(rig)
        light = sun.data
        bpy.data.objects.remove(sun)                                  # no longer in the scene: not the fixture's
        bpy.data.lights.remove(light)
    assert [w for w in got[-1]["warnings"] if "Linking" in w] == [
        "Lixel: Light 'Sun' has Shadow Linking to collection 'lixel_test linking' but is an instance (of a "
        "collection instance): Lixel does not follow it and lights and shadows every object; make it a real object "
        "(Object > Apply > Make Instances Real) to have its linking followed"]
    assert got[-1]["result"].shadow_mask.max() > 0.9


@pytest.mark.parametrize("attr", ["receiver_collection", "blocker_collection"])
def test_the_viewport_picture_follows_light_and_shadow_linking(engine, scene, lixel, attr):
    """The 3D view's picture (``addon/ui/renders.py`` ``pip_textures``) is drawn as the engine draws: the box
    excluded from the Sun's receivers is not lit by it (its pixels get the world's light alone, the others stay
    as they were); excluded from its blockers, its shadow is gone."""
    renders = importlib.import_module(lixel.__name__ + ".addon.ui.renders")
    live = importlib.import_module(lixel.__name__ + ".addon.ui.live")
    describe = importlib.import_module(lixel.__name__ + ".addon.scene.describe")
    build(scene)
    scene.lixel.eye_blur = 0.0

    def picture():
        dg = describe.evaluated_depsgraph(scene)
        return renders.pip_images(live.update(scene, dg), dg, 96, False, True)["scene"]
    plain = picture()
    coll = _link(scene, attr, {scene.objects["Box"]: "EXCLUDE"})
    try:
        linked = picture()
    finally:
        _unlink(coll)
    changed = np.any(linked != plain, axis=-1)
    assert changed.sum() > 100
    if attr == "receiver_collection":      # darker: the world's light alone
        assert (linked[changed][:, :3] < plain[changed][:, :3]).all()
        assert np.ptp(linked[changed][:, :3], axis=0).max() == 0.0
    else:                                  # lighter: its shadow gone
        assert (linked[changed][:, :3] > plain[changed][:, :3]).all()


@pytest.mark.parametrize("attr", ["receiver_collection", "blocker_collection"])
@pytest.mark.parametrize("linked", ["instancer", "instanced object"])
@pytest.mark.parametrize("kind", ["collection", "nodes"])
def test_an_instance_follows_its_instancer_and_a_collection_instance_its_own_object_too(engine, scene, kind,
                                                                                          linked, attr):
    """Cycles (4.2.23 and 5.0.1) excludes an instance from the light's Light or Shadow Linking when its instancer is
    excluded: an empty instancing a collection, or an object whose geometry nodes make instances; an instance of a
    collection instance is also excluded when its own object is, geometry-nodes instances are not. Lixel follows
    Cycles, through both of its readers of instances (the walk, and in 4.3+ the array reader)."""
    build(scene)
    instanced = bpy.data.objects.new("Linked", cube_mesh("Linked", 0.9, 0.0))
    host = _instancer(scene, kind, instanced)
    try:
        plain, got = _with_and_without(engine, scene, attr, {host if linked == "instancer" else instanced: "EXCLUDE"})
    finally:
        _remove_instancer(host, instanced)
    res, ref = got["result"], plain["result"]
    seen = _instanced_pixels(ref.world_position)
    assert seen.sum() > 100
    if linked == "instanced object" and kind == "nodes":        # its own entry does not count
        np.testing.assert_array_equal(res.combined, ref.combined)
        np.testing.assert_array_equal(res.shadow_mask, ref.shadow_mask)
    elif attr == "receiver_collection":                        # not lit by the sun, the rest as before
        np.testing.assert_array_equal(res.combined[seen][:, :3], np.broadcast_to(_world_lit(ref), (seen.sum(), 3)))
        np.testing.assert_array_equal(res.combined[~seen], ref.combined[~seen])
    else:                                                      # its shadow is gone, it is lit as before
        assert (res.shadow_mask > 0.5).sum() < (ref.shadow_mask > 0.5).sum() - 20
        np.testing.assert_array_equal(res.combined[seen], ref.combined[seen])
