"""Camera scale is ignored exactly as Blender ignores it: what Lixel's engine
covers is what Workbench covers, for perspective and orthographic cameras and
shifted lenses, whatever the camera object's scale; a panoramic camera is
refused by name at any scale."""
import math

import bpy
import numpy as np
import pytest
from mathutils import Vector

W, H = 64, 48
MISMATCH = 0.02
"""Fraction of pixels allowed to differ: silhouette edges, where Workbench's
antialiasing and Lixel's single sample split a pixel differently."""


def _mesh(name, verts, faces):
    me = bpy.data.meshes.new(name)
    me.from_pydata(verts, [], faces)
    return me


def _box(name, lo, hi):
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = [(x, y, z) for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)]
    return _mesh(name, v, [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])


@pytest.fixture
def scene(fresh_scene):
    sc = fresh_scene
    for name, data in (("Ground", _mesh("Ground", [(-4, -3, 0), (4, -3, 0), (4, 3, 0), (-4, 3, 0)], [(0, 1, 2, 3)])),
                       ("Tower", _box("Tower", (-1.0, -0.5, 0), (0.0, 0.5, 2.5))),
                       ("Block", _box("Block", (1.2, -1.5, 0), (2.4, 0.2, 0.8)))):
        sc.collection.objects.link(bpy.data.objects.new(name, data))
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    sc.collection.objects.link(cam)
    cam.location = (2.0, -9.0, 5.0)
    cam.rotation_euler = (Vector((0.3, 0.0, 0.8)) - cam.location).to_track_quat("-Z", "Y").to_euler()
    cam.data.clip_start, cam.data.clip_end = 0.5, 40.0
    sc.camera = cam
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.rotation_euler = (math.radians(35), 0.0, math.radians(25))
    sc.collection.objects.link(sun)
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = W, H, 100
    sc.render.film_transparent = True
    if getattr(sc, "lixel", None) is not None:
        sc.lixel.initialised = True
        sc.lixel.shadow_map_size = (256, 256)
    yield sc


def workbench_coverage(scene, tmp_path) -> np.ndarray:
    """(H, W) bool: pixels Workbench covers (alpha of a transparent-film render), row 0 at the bottom."""
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    path = tmp_path / "workbench.png"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True, scene=scene.name)
    img = bpy.data.images.load(str(path))
    try:
        px = np.empty(W * H * 4, dtype=np.float32)
        img.pixels.foreach_get(px)
    finally:
        bpy.data.images.remove(img)
    return px.reshape(H, W, 4)[..., 3] > 0.5


def lixel_coverage(engine, scene) -> np.ndarray:
    scene.render.engine = "LIXEL"
    with engine.watch_renders(read={"covered"}) as got:
        assert bpy.ops.render.render(scene=scene.name) == {"FINISHED"}
    return got[-1]["result"].covered


def _set_lens(cam, kind):
    if kind == "ortho":
        cam.data.type = "ORTHO"
        cam.data.ortho_scale = 9.0
    elif kind == "shifted":
        cam.data.shift_x, cam.data.shift_y = 0.25, -0.15
        cam.data.lens = 35.0


SCALES = [(1, 1, 1), (2, 2, 2), (0.01, 0.01, 0.01), (3.0, 0.5, 1.7), (1e-4, 2e3, 1.0)]


@pytest.mark.parametrize("lens", ["perspective", "ortho", "shifted"])
def test_lixel_covers_what_workbench_covers_at_any_camera_scale(engine, scene, tmp_path, lens):
    cam = scene.camera
    _set_lens(cam, lens)
    reference = None
    for scale in SCALES:
        cam.scale = scale
        bpy.context.view_layer.update()
        wb = workbench_coverage(scene, tmp_path)
        lx = lixel_coverage(engine, scene)
        assert 0.2 < wb.mean() < 0.95, "the scene must fill part of the view"
        assert (wb != lx).mean() < MISMATCH, f"{lens} camera at scale {scale}"
        if reference is None:
            reference = lx
        else:  # and exactly what the unscaled camera gives
            assert (lx != reference).mean() < 0.002, f"{lens} camera at scale {scale}"


@pytest.mark.parametrize("parent_scale", [(0.1, 0.1, 0.1), (2.5, 1.0, 0.7)])
def test_a_camera_under_a_scaled_parent_renders_as_blender_does(engine, scene, tmp_path, parent_scale):
    """A rig's scale reaches the camera's matrix_world (non-uniform: sheared axes),
    and Blender still only normalises the axes."""
    parent = bpy.data.objects.new("Rig", None)
    scene.collection.objects.link(parent)
    parent.scale = parent_scale
    cam = scene.camera
    cam.parent = parent
    cam.location = [c / s for c, s in zip(cam.location, parent_scale)]  # the same place in the world
    bpy.context.view_layer.update()
    assert (cam.matrix_world.translation - Vector((2.0, -9.0, 5.0))).length < 1e-4
    wb = workbench_coverage(scene, tmp_path)
    assert 0.2 < wb.mean() < 0.95
    assert (wb != lixel_coverage(engine, scene)).mean() < MISMATCH


@pytest.mark.parametrize("scale", [(1, 1, 1), (2, 2, 2), (0.01, 0.01, 0.01)])
def test_a_panoramic_camera_is_refused_by_name_at_any_scale(engine, scene, scale, capfd):
    scene.camera.data.type = "PANO"
    scene.camera.scale = scale
    scene.render.engine = "LIXEL"
    with pytest.raises(RuntimeError, match=r"Camera 'Cam' is panoramic: Lixel renders perspective and orthographic"):
        bpy.ops.render.render(scene=scene.name)
    assert "Traceback" not in capfd.readouterr().err


@pytest.mark.parametrize("scale,axes", [((0, 0, 0), "X, Y, Z axes"), ((1, 1, 0), "Z axis"), ((1, 0, 1), "Y axis")])
def test_a_zero_scale_camera_is_refused_by_name(engine, scene, scale, axes, capfd):
    scene.camera.scale = scale
    scene.render.engine = "LIXEL"
    with pytest.raises(RuntimeError, match=rf"Camera 'Cam' has zero scale on its {axes} \(or a parent's\)"):
        bpy.ops.render.render(scene=scene.name)
    assert "Traceback" not in capfd.readouterr().err
