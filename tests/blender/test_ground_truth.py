"""The ray-cast ground truth on scenes with a known answer."""
import math

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from addon.scene.describe import describe_scene  # noqa: E402
from bench.report import ground_truth as G  # noqa: E402

H_CAM, FOV, RES = 20.0, math.radians(30.0), 400


def _mesh(scene, name, verts, faces):
    me = bpy.data.meshes.new(name)
    me.from_pydata(verts, [], faces)
    ob = bpy.data.objects.new(name, me)
    scene.collection.objects.link(ob)
    return ob


def _turned(x, y, z, deg=20.0):
    # the plate is turned about Z so its edges do not line up with the pixel grid
    # (an aligned square's pixel count jumps by a whole row at once)
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return (c * x - s * y, s * x + c * y, z)


def _build(scene, light_type, light_at=None, sun_dir=None):
    made = [_mesh(scene, "gt_ground", [(-10, -10, 0), (10, -10, 0), (10, 10, 0), (-10, 10, 0)], [(0, 1, 2, 3)]),
            _mesh(scene, "gt_plate", [_turned(x, y, 1.0) for x, y in ((-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5))],
                  [(0, 1, 2, 3)])]
    cam = bpy.data.cameras.new("gt_cam")
    cam.sensor_fit = "HORIZONTAL"
    cam.angle = FOV
    cam.clip_start, cam.clip_end = 1.0, 50.0
    cam_ob = bpy.data.objects.new("gt_cam", cam)
    cam_ob.location = (0, 0, H_CAM)                       # looks straight down (-Z)
    scene.collection.objects.link(cam_ob)
    scene.camera = cam_ob
    lt = bpy.data.lights.new("gt_light", light_type)
    lt_ob = bpy.data.objects.new("gt_light", lt)
    scene.collection.objects.link(lt_ob)
    if sun_dir is not None:
        from mathutils import Vector
        lt_ob.rotation_euler = Vector(sun_dir).to_track_quat("-Z", "Y").to_euler()
    if light_at is not None:
        lt_ob.location = light_at
    scene.render.resolution_x = scene.render.resolution_y = RES
    scene.render.resolution_percentage = 100
    return made + [cam_ob, lt_ob]


def _cleanup(objs):
    for ob in objs:
        data = ob.data
        bpy.data.objects.remove(ob)
        if data is not None and data.users == 0:
            {"MESH": bpy.data.meshes, "CAMERA": bpy.data.cameras}.get(
                getattr(data, "id_type", ""), bpy.data.lights if isinstance(data, bpy.types.Light) else bpy.data.meshes
            ).remove(data)


def _truth(scene):
    view, light, bounds = describe_scene(scene)
    dg = scene.view_layers[0].depsgraph
    bvh = G.build_bvh(G.scene_triangles(dg))
    return view, light, G.ground_truth(view, light, bvh, bounds.scale())


def _shadow_area_on_ground(gt):
    on_ground = gt.hit & (np.abs(gt.points[..., 2]) < 1e-4)
    pixel = 2 * H_CAM * math.tan(FOV / 2) / RES            # ground length of one pixel (top-down view)
    return float((gt.shadow & on_ground & gt.valid).sum()) * pixel * pixel


@pytest.mark.parametrize("tilt_deg", [50.0, 65.0])
def test_sun_shadow_of_a_plate_has_the_plate_area(fresh_scene, tilt_deg):
    # a horizontal 1 m² plate projects along parallel rays onto the horizontal ground
    # as a translated copy: area 1 m², offset by tan(tilt) m (outside the plate's own view)
    t = math.radians(tilt_deg)
    objs = _build(fresh_scene, "SUN", sun_dir=(math.sin(t), 0.0, -math.cos(t)))
    try:
        view, light, gt = _truth(fresh_scene)
        assert _shadow_area_on_ground(gt) == pytest.approx(1.0, rel=0.015)
        # the shadow is where it should be: pixels around the shadow's centre are dark
        centre = np.array([math.tan(t), 0.0, 0.0])
        near = np.linalg.norm(gt.points - centre, axis=2) < 0.25
        assert near.any() and gt.shadow[near].all()
        plate = gt.hit & (np.abs(gt.points[..., 2] - 1.0) < 1e-4)
        assert plate.any() and not gt.shadow[plate].any()      # the plate's top is lit
    finally:
        _cleanup(objs)


def test_point_light_shadow_of_a_plate_is_scaled_by_the_light_height(fresh_scene):
    # light 5 m up, plate 1 m up: the shadow is the plate scaled by 5/4 about the light's foot
    objs = _build(fresh_scene, "POINT", light_at=(-8.0, 0.0, 5.0))
    try:
        view, light, gt = _truth(fresh_scene)
        assert _shadow_area_on_ground(gt) == pytest.approx(1.25 ** 2, rel=0.015)
    finally:
        _cleanup(objs)


def test_pixels_follow_blender_orientation(fresh_scene):
    # row 0 is the bottom of the image: with the camera looking down and +Y up on screen,
    # the first row sees the most negative world Y
    objs = _build(fresh_scene, "SUN", sun_dir=(0.5, 0.0, -1.0))
    try:
        view, light, gt = _truth(fresh_scene)
        assert gt.points[0, RES // 2, 1] < gt.points[-1, RES // 2, 1]
        assert gt.points[RES // 2, 0, 0] < gt.points[RES // 2, -1, 0]
        assert gt.valid.sum() == RES * RES                    # everything is ground or plate, facing the sun
    finally:
        _cleanup(objs)


def test_grazing_sun_shadow_ends_where_the_occluders_edge_sends_it(fresh_scene):
    # a sun 89.3° from the zenith (n·l = 0.0125 on the ground) over a wall 0.1 m high at x = -5: its shadow
    # on the ground ends at x = -5 + 0.1 tan t. A shadow ray moved off the ground along the normal would pass
    # the wall's top edge eps higher and end the shadow eps tan t (~2 pixels) short
    t = math.atan(80.0)
    objs = _build(fresh_scene, "SUN", sun_dir=(math.sin(t), 0.0, -math.cos(t)))
    objs.append(_mesh(fresh_scene, "gt_wall", [(-5, -3, 0), (-5, -1, 0), (-5, -1, 0.1), (-5, -3, 0.1)], [(0, 1, 2, 3)]))
    try:
        view, light, gt = _truth(fresh_scene)
        row = gt.hit & (np.abs(gt.points[..., 1] + 2.0) < 0.02) & (np.abs(gt.points[..., 2]) < 1e-4)
        x = gt.points[..., 0]
        end = float(x[row & gt.shadow].max())
        pixel = 2 * H_CAM * math.tan(FOV / 2) / RES
        assert abs(end - (-5.0 + 0.1 * 80.0)) <= pixel
        assert not gt.shadow[row & (x > -5.0 + 0.1 * 80.0 + pixel)].any()
    finally:
        _cleanup(objs)


def test_a_box_standing_in_a_grazed_receiver_shadows_it_however_near_the_plane(fresh_scene):
    # a point light 0.5 mm over the ground (n·l ~ 1e-4 there) and a box standing in the ground between it and
    # the ground beyond: every shadow ray from there passes through the box, 0.1-0.4 mm over the ground, and is
    # shadowed. A ray started eps above the ground (eps / n·l, metres, along it) would start past the box.
    # The ground itself, grazed, is no occluder: beside the box's shadow it is lit
    objs = _build(fresh_scene, "POINT", light_at=(-5.0, 2.5, 0.0005))
    v = [(x, y, z) for z in (-0.1, 0.3) for y in (2.0, 3.0) for x in (-2.0, -1.0)]
    objs.append(_mesh(fresh_scene, "gt_box", v, [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4),
                                                 (1, 5, 7, 3)]))
    try:
        view, light, gt = _truth(fresh_scene)
        x, y = gt.points[..., 0], gt.points[..., 1]
        ground = gt.hit & gt.valid & (np.abs(gt.points[..., 2]) < 1e-4) & (x > 0.0)
        behind = ground & (np.abs(y - 2.5) < 0.4 * (x + 5.0) / 4.0)      # inside the far face's wedge
        beside = ground & (np.abs(y - 2.5) > 0.6 * (x + 5.0) / 3.0)      # outside the near face's
        assert behind.sum() > 1000 and beside.sum() > 1000
        assert gt.shadow[behind].all()
        assert not gt.shadow[beside].any()
    finally:
        _cleanup(objs)


def test_a_pixel_where_the_render_shows_another_face_than_the_ray_caster_is_not_compared():
    """At a box's edge the rasterizer (its vertices snapped to sub-pixel steps) and the ray caster can see the same
    point on different faces, whose shadows differ: such a crease pixel is no shadow error and is left out, as a
    silhouette pixel is; the same point on the same face is compared."""
    from bench.report.run import comparable_mask
    side, top = np.array([-1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
    points = np.array([[[5.0, 1.0, 2.0], [5.0, 1.0, 2.0], [5.0, 1.001, 2.0]]])
    truth = G.GroundTruth(hit=np.ones((1, 3), bool), points=points, normals=np.stack([[side, side, side]]),
                          shadow=np.zeros((1, 3), bool), valid=np.ones((1, 3), bool), camera=np.zeros(3))
    frame = {"world_position": points + [[[1e-5, 0, 0], [1e-5, 0, 0], [0, 0, 0]]], "covered": np.ones((1, 3), bool)}
    assert comparable_mask(truth, frame).tolist() == [[True, True, True]]   # no normals read: points decide
    seen = np.stack([[side * (1 - 1e-8), top, -side]])          # the same face (either side), another face, the same
    assert comparable_mask(truth, {**frame, "world_normal": seen}).tolist() == [[True, False, True]]
