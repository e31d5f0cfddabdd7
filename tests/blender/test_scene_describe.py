"""addon.scene.describe: bpy -> View, Light, SceneBounds.

The projection is checked against Blender's own camera mapping
(``bpy_extras.object_utils.world_to_camera_view`` and ``Camera.view_frame``),
which is computed independently of ``calc_matrix_camera``.
"""
import importlib
import math

import bpy
import numpy as np
import pytest
from mathutils import Vector


@pytest.fixture(scope="module")
def describe(lixel):
    return importlib.import_module(lixel.__name__ + ".addon.scene.describe")


@pytest.fixture(scope="module")
def types_mod(lixel):
    return importlib.import_module(lixel.__name__ + ".addon.warp.types")


def _link(scene, ob):
    scene.collection.objects.link(ob)
    return ob


def add_camera(scene, name="Cam", location=(0.3, -6.0, 2.5), rotation=(math.radians(70), 0.1, 0.2), **data):
    cam = bpy.data.cameras.new(name)
    for k, v in data.items():
        setattr(cam, k, v)
    ob = _link(scene, bpy.data.objects.new(name, cam))
    ob.location = location
    ob.rotation_euler = rotation
    scene.camera = ob
    return ob


def add_light(scene, kind, name=None, location=(1.0, 2.0, 5.0), rotation=(0.3, -0.4, 0.5), **data):
    name = name or kind.title()
    lt = bpy.data.lights.new(name, kind)
    for k, v in data.items():
        setattr(lt, k, v)
    ob = _link(scene, bpy.data.objects.new(name, lt))
    ob.location = location
    ob.rotation_euler = rotation
    return ob


def add_cube(scene, name="Box", location=(0, 0, 0), size=1.0):
    me = bpy.data.meshes.new(name)
    h = size / 2
    verts = [(x, y, z) for x in (-h, h) for y in (-h, h) for z in (-h, h)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    me.from_pydata(verts, [], faces)
    ob = _link(scene, bpy.data.objects.new(name, me))
    ob.location = location
    return ob


def _depsgraph(scene):
    dg = scene.view_layers[0].depsgraph
    dg.update()
    return dg


def _project(view, points):
    h = np.c_[points, np.ones(len(points))] @ view.world_to_clip.T
    return h[:, :2] / h[:, 3:4]


def _blender_ndc(scene, cam_ob, points):
    from bpy_extras.object_utils import world_to_camera_view
    return np.array([tuple(world_to_camera_view(scene, cam_ob, Vector(p)))[:2] for p in points]) * 2 - 1


CAMERA_CASES = {
    "auto-landscape": dict(res=(320, 180), pct=100, cam={}),
    "auto-portrait": dict(res=(180, 320), pct=50, cam={}),
    "horizontal-fit-portrait": dict(res=(200, 300), pct=100, cam=dict(sensor_fit="HORIZONTAL")),
    "vertical-fit-landscape": dict(res=(300, 200), pct=100, cam=dict(sensor_fit="VERTICAL", sensor_height=18.0)),
    "lens-shift": dict(res=(400, 300), pct=75, cam=dict(shift_x=0.2, shift_y=-0.15, lens=35.0)),
    "pixel-aspect": dict(res=(300, 300), pct=100, cam=dict(lens=70.0), aspect=(2.0, 1.0)),
    "ortho-shift": dict(res=(300, 200), pct=100, cam=dict(type="ORTHO", ortho_scale=9.0, shift_x=0.1)),
}


@pytest.mark.parametrize("case", sorted(CAMERA_CASES))
def test_projection_matches_blender_camera(describe, fresh_scene, case):
    c = CAMERA_CASES[case]
    scene = fresh_scene
    scene.render.resolution_x, scene.render.resolution_y = c["res"]
    scene.render.resolution_percentage = c["pct"]
    if "aspect" in c:
        scene.render.pixel_aspect_x, scene.render.pixel_aspect_y = c["aspect"]
    cam = add_camera(scene, **c["cam"])
    dg = _depsgraph(scene)
    view = describe.describe_view(cam, dg, scene)
    cam = cam.evaluated_get(dg)  # 4.2 does not flush matrix_world back for a scene that is not the window's

    assert view.resolution == (c["res"][0] * c["pct"] // 100, c["res"][1] * c["pct"] // 100)
    assert view.orthographic == (c["cam"].get("type") == "ORTHO")
    assert view.near == pytest.approx(cam.data.clip_start) and view.far == pytest.approx(cam.data.clip_end)
    np.testing.assert_allclose(view.camera_to_world, np.array(cam.matrix_world), atol=1e-6)

    rng = np.random.default_rng(7)
    local = np.c_[rng.uniform(-3, 3, (50, 2)), -rng.uniform(1, 30, 50)]
    world = np.array([tuple(cam.matrix_world @ Vector(p)) for p in local])
    np.testing.assert_allclose(_project(view, world), _blender_ndc(scene, cam, world), atol=2e-5)

    # The camera frame Blender draws (sensor fit, shift, aspect) is exactly NDC x, y = +-1.
    frame = [cam.matrix_world @ v for v in cam.data.view_frame(scene=scene)]
    ndc = _project(view, np.array([tuple(v) for v in frame]))
    np.testing.assert_allclose(np.sort(np.abs(ndc).ravel()), np.ones(8), atol=1e-5)


def test_near_and_far_planes_map_to_gl_depth(describe, fresh_scene):
    cam = add_camera(fresh_scene, clip_start=0.25, clip_end=40.0)
    dg = _depsgraph(fresh_scene)
    view = describe.describe_view(cam, dg, fresh_scene)
    cam = cam.evaluated_get(dg)
    for dist, z in ((0.25, -1.0), (40.0, 1.0)):
        p = np.array(cam.matrix_world @ Vector((0.1, 0.05, -dist)))
        h = view.world_to_clip @ np.append(p, 1.0)
        assert h[2] / h[3] == pytest.approx(z, abs=1e-5)


def test_sun_spot_point_area(describe, fresh_scene):
    scene = fresh_scene
    sun = add_light(scene, "SUN", energy=3.0, color=(1.0, 0.5, 0.25))
    spot = add_light(scene, "SPOT", spot_size=math.radians(50))
    point = add_light(scene, "POINT", location=(4, 5, 6))
    area = add_light(scene, "AREA", spread=math.radians(120))
    wide = add_light(scene, "AREA", name="WideArea")
    dg = _depsgraph(scene)

    s = describe.describe_light(sun, dg)
    minus_z = -np.array(sun.matrix_basis.to_3x3().col[2])
    np.testing.assert_allclose(s.direction, minus_z / np.linalg.norm(minus_z), atol=1e-6)
    assert s.type == "SUN" and s.energy == pytest.approx(3.0)
    np.testing.assert_allclose(s.color, (1.0, 0.5, 0.25), atol=1e-6)
    assert s.name == sun.name

    sp = describe.describe_light(spot, dg)
    assert sp.type == "SPOT" and sp.spot_angle == pytest.approx(math.radians(50), rel=1e-6)
    np.testing.assert_allclose(sp.position, (1.0, 2.0, 5.0), atol=1e-6)
    np.testing.assert_allclose(sp.direction, s.direction, atol=1e-6)  # same rotation

    p = describe.describe_light(point, dg)
    assert p.type == "POINT"
    np.testing.assert_allclose(p.position, (4, 5, 6), atol=1e-6)

    a = describe.describe_light(area, dg)
    assert a.type == "SPOT" and a.spot_angle == pytest.approx(math.radians(120), rel=1e-6)
    assert describe.describe_light(wide, dg).spot_angle == pytest.approx(math.radians(179), rel=1e-6)


def test_errors_name_the_object_and_the_fix(describe, types_mod, fresh_scene):
    scene = fresh_scene
    add_cube(scene)
    with pytest.raises(types_mod.WarpError, match=r"Scene 'lixel_test.*' has no camera: add a camera"):
        describe.describe_scene(scene)
    add_camera(scene)
    with pytest.raises(types_mod.WarpError, match=r"has no light: add a Sun"):
        describe.describe_scene(scene)
    box = scene.objects["Box"]
    with pytest.raises(types_mod.WarpError, match=r"Object 'Box' is a mesh, not a light"):
        describe.describe_scene(scene, light=box)
    with pytest.raises(types_mod.WarpError, match=r"Object 'Box' is a mesh, not a camera"):
        describe.describe_scene(scene, camera=box)
    empty = bpy.data.objects.new("Empty", None)
    scene.collection.objects.link(empty)
    with pytest.raises(types_mod.WarpError, match=r"Object 'Empty' is an empty, not a camera"):
        describe.describe_scene(scene, camera=empty)
    bpy.data.objects.remove(empty)
    scene.render.resolution_percentage = 1
    scene.render.resolution_x = 50
    with pytest.raises(types_mod.WarpError, match=r"renders at 0x"):
        describe.describe_view(scene.camera, _depsgraph(scene), scene)
    scene.render.resolution_percentage = 100
    scene.camera.data.type = "PANO"
    with pytest.raises(types_mod.WarpError, match=r"Camera 'Cam.*' is panoramic"):
        describe.describe_view(scene.camera, _depsgraph(scene), scene)


def test_empty_scene_is_reported(describe, types_mod, fresh_scene):
    add_camera(fresh_scene)
    add_light(fresh_scene, "SUN")
    with pytest.raises(types_mod.WarpError, match=r"no visible faces"):
        describe.describe_scene(fresh_scene)


def test_light_choice_prefers_sun_then_any(describe, fresh_scene):
    scene = fresh_scene
    add_camera(scene)
    add_cube(scene)
    add_light(scene, "POINT", name="A_point")
    _, light, _ = describe.describe_scene(scene)
    assert light.name == "A_point"
    add_light(scene, "SUN", name="Z_sun")
    _, light, _ = describe.describe_scene(scene)
    assert light.name == "Z_sun"
    _, light, _ = describe.describe_scene(scene, light="A_point")
    assert light.name == "A_point"
    props = getattr(scene, "lixel", None)
    if props is not None and hasattr(props, "light"):  # the Lixel light setting wins over the sun
        props.light = scene.objects["A_point"]
        _, light, _ = describe.describe_scene(scene)
        assert light.name == "A_point"
        props.light = None


def test_bounds_cover_modifiers_instances_and_shadow_visibility(describe, fresh_scene):
    scene = fresh_scene
    add_camera(scene)
    add_light(scene, "SUN")
    ground = add_cube(scene, "Ground", location=(0, 0, -1))
    ground.scale = (10, 10, 0.1)
    ground.visible_shadow = False
    box = add_cube(scene, "Box", location=(0, 0, 1))
    arr = box.modifiers.new("arr", "ARRAY")
    arr.count = 3  # 3 m long along local X after the modifier
    # Geometry-nodes host: 4 points, each instancing a 0.5 m cube created in the tree.
    host = add_cube(scene, "Host", location=(20, 0, 0))
    ng = bpy.data.node_groups.new("lixel_test_points", "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    gi, go = ng.nodes.new("NodeGroupInput"), ng.nodes.new("NodeGroupOutput")
    grid = ng.nodes.new("GeometryNodeMeshGrid")
    grid.inputs["Size X"].default_value = 4.0
    grid.inputs["Size Y"].default_value = 4.0
    grid.inputs["Vertices X"].default_value = 2
    grid.inputs["Vertices Y"].default_value = 2
    cube = ng.nodes.new("GeometryNodeMeshCube")
    cube.inputs["Size"].default_value = (0.5, 0.5, 0.5)
    iop = ng.nodes.new("GeometryNodeInstanceOnPoints")
    ng.links.new(grid.outputs["Mesh"], iop.inputs["Points"])
    ng.links.new(cube.outputs["Mesh"], iop.inputs["Instance"])
    ng.links.new(iop.outputs["Instances"], go.inputs[0])
    mod = host.modifiers.new("gn", "NODES")
    mod.node_group = ng
    try:
        dg = _depsgraph(scene)
        inst = describe.walk_instances(dg)
        bounds = describe.describe_bounds(dg, inst)
        assert len(bounds.receivers) == 2 + 4   # ground, box, 4 GN instances (the host shows only instances)
        assert len(bounds.casters) == 1 + 4     # the ground does not cast
        boxes = {tuple(np.round(b.ravel(), 4)) for b in bounds.receivers}
        assert (-0.5, -0.5, 0.5, 2.5, 0.5, 1.5) in boxes          # array modifier applied
        for x in (18, 22):
            for y in (-2, 2):
                assert (x - .25, y - .25, -.25, x + .25, y + .25, .25) in boxes  # instance matrices copied
        gn_keys = {k for k in inst.keys if k[0] == "GN"}
        assert len(gn_keys) == 1  # one batch for the four instances
    finally:
        bpy.data.node_groups.remove(ng)


@pytest.mark.parametrize("kind", ["PERSP", "ORTHO"])
def test_depth_rows_are_blenders_in_float64(describe, fresh_scene, kind):
    """Blender's calc_matrix_camera is float32: at a clip range of 1:1e7 its far
    plane lands at infinity. The description keeps Blender's x, y rows and puts
    the exact depth rows beside them."""
    cam = add_camera(fresh_scene, type=kind, clip_start=0.25, clip_end=40.0, ortho_scale=8.0)
    dg = _depsgraph(fresh_scene)
    blender = np.array(cam.evaluated_get(dg).calc_matrix_camera(dg, x=1920, y=1080), dtype=np.float64)
    view = describe.describe_view(cam, dg, fresh_scene)
    np.testing.assert_allclose(view.projection, blender, rtol=1e-6, atol=1e-7)
    cam.data.clip_start, cam.data.clip_end = 1e-4, 1e3
    dg = _depsgraph(fresh_scene)
    view = describe.describe_view(cam, dg, fresh_scene)
    inv = np.linalg.inv(view.projection)
    for z_ndc, depth in ((-1.0, cam.data.clip_start), (1.0, cam.data.clip_end)):  # Blender's float32 values
        h = inv @ np.array([0.3, -0.2, z_ndc, 1.0])
        assert -h[2] / h[3] == pytest.approx(depth, rel=1e-9)


def test_a_clip_range_beyond_float_precision_is_refused_by_name(describe, types_mod, fresh_scene):
    cam = add_camera(fresh_scene, name="Wide", clip_start=1e-6, clip_end=1e9)
    with pytest.raises(types_mod.WarpError, match=r"Camera 'Wide' clips from 1 µm to 1e\+09 m, a range of 1:1e\+15, "
                                                  r"beyond what 32-bit float depth resolves .*raise the clip start"):
        describe.describe_view(cam, _depsgraph(fresh_scene), fresh_scene)
    cam.data.clip_start, cam.data.clip_end = 1e-3, 1e4  # 1:1e7 is still resolved
    assert describe.describe_view(cam, _depsgraph(fresh_scene), fresh_scene).far == pytest.approx(1e4)


@pytest.mark.parametrize("what,change,pattern", [
    ("camera", lambda ob: setattr(ob, "location", (float("nan"), 0, 0)),
     r"Camera 'Cam' has a non-finite transform \(NaN or infinity"),
    ("camera", lambda ob: setattr(ob, "location", (float("inf"), 0, 0)),
     r"Camera 'Cam' has a non-finite transform"),
    ("camera", lambda ob: setattr(ob, "scale", (0, 0, 0)), r"Camera 'Cam' has zero scale on its X, Y, Z axes"),
    ("camera", lambda ob: setattr(ob, "scale", (1, 1, 0)), r"Camera 'Cam' has zero scale on its Z axis"),
    ("light", lambda ob: setattr(ob, "location", (0, float("nan"), 0)),
     r"Light 'Sun' has a non-finite transform \(NaN or infinity"),
    ("light", lambda ob: setattr(ob, "scale", (0, 0, 0)), r"Light 'Sun' has zero scale on its Z axis"),
    ("light", lambda ob: setattr(ob, "scale", (1, 1, 0)), r"Light 'Sun' has zero scale on its Z axis"),
    ("box", lambda ob: setattr(ob, "scale", (float("nan"), 1, 1)), r"Object 'Box' has a non-finite transform"),
    ("box", lambda ob: ob.data.vertices[0].co.__setitem__(0, float("inf")),
     r"Object 'Box' has vertices with non-finite coordinates"),
    ("box", lambda ob: setattr(ob, "location", (0, -3e13, 0)),        # a typo in the N panel: named, not "the scene"
     r"Object 'Box' reaches 3e\+13 m from the origin, beyond the 1e\+12 m Lixel can compute with: move it closer"),
])
def test_degenerate_cameras_lights_and_objects_are_named(describe, types_mod, fresh_scene, what, change, pattern):
    cam = add_camera(fresh_scene)
    sun = add_light(fresh_scene, "SUN")
    box = add_cube(fresh_scene)
    change({"camera": cam, "light": sun, "box": box}[what])
    fresh_scene.view_layers[0].update()
    with pytest.raises(types_mod.WarpError, match=pattern):
        describe.describe_scene(fresh_scene)


def test_a_point_light_needs_no_orientation(describe, fresh_scene):
    """Blender lights a zero-scale point light from its location; so does Lixel."""
    point = add_light(fresh_scene, "POINT", location=(1, 2, 3))
    point.scale = (0, 0, 0)
    light = describe.describe_light(point, _depsgraph(fresh_scene))
    np.testing.assert_allclose(light.position, (1, 2, 3))


def test_light_notes_say_what_renders_differently(describe, fresh_scene):
    sun = add_light(fresh_scene, "SUN", energy=0.0)
    area = add_light(fresh_scene, "AREA")
    assert describe.light_notes(sun) == [
        "Light 'Sun' has a strength of 0: it lights nothing, so its shadows show only in the Shadow pass "
        "(Light properties > Power/Strength)"]
    sun.data.energy = -2.0          # Cycles subtracts a negative light: it does not light nothing
    assert describe.light_notes(sun) == [
        "Light 'Sun' has a negative strength (-2): it takes light away, as in Cycles, so its shadows are the "
        "brighter places (Light properties > Power/Strength)"]
    assert describe.light_notes(area) == [
        "Area light 'Area' is shadowed as a spot light at its centre (hard shadows, cone = its spread, at most 179°)"]
    spot = add_light(fresh_scene, "SPOT", spot_size=math.pi)   # Blender's widest spot: no perspective map covers it
    assert describe.describe_light(spot).spot_angle == pytest.approx(math.radians(179.0))
    assert describe.light_notes(spot) == [
        "Spot light 'Spot' has a cone of 180°: Lixel lights and shadows its 179° (no perspective map covers 180°); "
        "the rim beyond is unlit"]
    spot.data.spot_size = math.radians(60.0)
    spot.scale = (-2.0, 2.0, 2.0)                         # even (a mirror is even): the cone Blender draws is round
    bpy.context.view_layer.update()
    assert describe.light_notes(spot) == []
    spot.scale = (3.0, 1.0, 1.0)                          # Blender lights a cone 3 times as wide along X
    bpy.context.view_layer.update()
    assert describe.light_notes(spot) == [
        "Spot light 'Spot' is scaled unevenly (X 3, Y 1 times its Z): Blender stretches its cone into an ellipse, "
        "Lixel lights and shadows the round cone of its Spot Size; give it an even scale (Object properties > "
        "Transform > Scale)"]


@pytest.mark.parametrize("view_used, expected", [("right", "Cam_R"), ("left", "Cam_L")])
def test_one_multiview_view_renders_with_its_own_camera_as_blender_does(describe, fresh_scene, view_used, expected):
    """Measured with Workbench (4.2.23, 5.0.1): scene camera "Cam_L", multi-view with only the right view on
    renders "Cam_R" (the camera's name with the view's suffix); Lixel describes that camera too."""
    scene = fresh_scene
    cams = {name: add_camera(scene, name, location=loc) for name, loc in (("Cam_R", (4, -6, 3)), ("Cam_L", (-4, -6, 3)))}
    assert scene.camera == cams["Cam_L"]
    _link(scene, bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN")))
    me = bpy.data.meshes.new("quad")
    me.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    _link(scene, bpy.data.objects.new("quad", me))
    scene.render.use_multiview, scene.render.views_format = True, "MULTIVIEW"
    for v in scene.render.views:
        v.use = v.name == view_used
    assert describe.render_camera(scene) == cams[expected]
    view, _, _ = describe.describe_scene(scene)
    np.testing.assert_allclose(view.camera_to_world[:3, 3], cams[expected].location, atol=1e-6)
    cams["Cam_L"].name = "Cam"                            # no view's suffix ends its name: the scene camera
    assert describe.render_camera(scene) == scene.camera
    scene.render.views_format = "STEREO_3D"                # (the engine takes each eye from Blender)
    cams["Cam_L"].name = "Cam_L"
    assert describe.render_camera(scene) == scene.camera
