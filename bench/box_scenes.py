"""Box scenes for judging rendered shadows against exact ray casting.

Each builder starts from an empty file and makes a ground, boxes, one camera
(no animation) and one light, the kinds of configuration the rendered-shadows
issue names: a sun from the side, from behind, low over a city; a forest of
thin trees; a spot-lit stage; point lights behind the camera and low in the view;
a box standing on the ground (contact). Geometry is exact boxes, so the ray-cast
ground truth sees exactly what the rasteriser draws.

    from bench.box_scenes import BOX_SCENES
    scene = BOX_SCENES["city_side_sun"]()
"""
from __future__ import annotations

import math

import bpy
import numpy as np

from sample_blends.scenes import _aim, add_sun, box, grid, merge, mesh_object, reset


def _camera(scene, location, target, fov_deg=60.0, near=0.1, far=150.0):
    cam = bpy.data.cameras.new("Camera")
    cam.sensor_fit = "HORIZONTAL"
    cam.angle = math.radians(fov_deg)
    cam.clip_start, cam.clip_end = near, far
    ob = bpy.data.objects.new("Camera", cam)
    scene.collection.objects.link(ob)
    scene.camera = ob
    _aim(ob, location, target)
    return ob


def _point(scene, location, energy=5000.0, name="Lamp"):
    lt = bpy.data.lights.new(name, "POINT")
    lt.energy = energy
    lt.shadow_soft_size = 0.0
    ob = bpy.data.objects.new(name, lt)
    scene.collection.objects.link(ob)
    ob.location = location
    return ob


def _spot(scene, location, target, cone_deg, energy=20000.0, name="Spot"):
    lt = bpy.data.lights.new(name, "SPOT")
    lt.energy = energy
    lt.spot_size = math.radians(cone_deg)
    lt.spot_blend = 0.0
    lt.shadow_soft_size = 0.0
    ob = bpy.data.objects.new(name, lt)
    scene.collection.objects.link(ob)
    _aim(ob, location, target)
    return ob


def _city(seed=7, extent=90.0, count=260):
    """A 240 m ground and ``count`` buildings of random footprint and height."""
    rng = np.random.default_rng(seed)
    mesh_object("Ground", *grid(np.linspace(-120, 120, 2), np.linspace(-120, 120, 2)))
    parts = []
    for _ in range(count):
        cx, cy = rng.uniform(-extent, extent, 2)
        if abs(cx) < 4.0:                      # keep a street open along +y at x = 0
            cx += 8.0 * np.sign(cx or 1.0)
        hx, hy = rng.uniform(0.6, 3.0, 2)
        parts.append(box((cx - hx, cy - hy, 0.0), (cx + hx, cy + hy, rng.uniform(1.0, 14.0))))
    mesh_object("Buildings", *merge(parts))


def _street_camera(scene):
    return _camera(scene, (0.0, -80.0, 1.8), (0.0, 20.0, 0.0), fov_deg=60.0, near=0.1, far=150.0)


def city_side_sun():
    """A street view, the sun from the side (15° off perpendicular to the view, towards the
    camera, so the walls facing the camera are not exactly edge-on to it), 35° high."""
    scene = reset()
    _city()
    _street_camera(scene)
    add_sun(scene, (1.0, -0.27, -math.tan(math.radians(35.0)) * math.hypot(1.0, 0.27)))
    return scene


def city_behind_sun():
    """A street view, the sun from behind the camera (30° high)."""
    scene = reset()
    _city()
    _street_camera(scene)
    add_sun(scene, (0.25, 1.0, -math.tan(math.radians(30.0))))
    return scene


def city_low_sun():
    """A street view, a sun 8° above the horizon from the side and ahead."""
    scene = reset()
    _city()
    _street_camera(scene)
    add_sun(scene, (0.8, -0.6, -math.tan(math.radians(8.0))))
    return scene


def forest_side_sun():
    """A forest of 1,500 thin trees (trunk and crown boxes), a sun from the side."""
    scene = reset()
    rng = np.random.default_rng(3)
    mesh_object("Ground", *grid(np.linspace(-100, 100, 2), np.linspace(-100, 100, 2)))
    parts = []
    for cx, cy in rng.uniform(-90, 90, (1500, 2)):
        h = rng.uniform(3.0, 7.0)
        parts.append(box((cx - 0.12, cy - 0.12, 0.0), (cx + 0.12, cy + 0.12, h * 0.4)))
        r = rng.uniform(0.6, 1.4)
        parts.append(box((cx - r, cy - r, h * 0.4), (cx + r, cy + r, h)))
    mesh_object("Trees", *merge(parts))
    _camera(scene, (-20.0, -60.0, 8.0), (0.0, -20.0, 1.0), fov_deg=60.0, near=0.1, far=70.0)
    add_sun(scene, (0.9, -0.2, -0.45))
    return scene


def stage_spot():
    """A stage with props under a 60° spot from above the front."""
    scene = reset()
    mesh_object("Floor", *grid(np.linspace(-15, 15, 2), np.linspace(-15, 15, 2)))
    rng = np.random.default_rng(5)
    parts = [box((x - 0.3, y - 0.3, 0.0), (x + 0.3, y + 0.3, rng.uniform(0.5, 2.5)))
             for x, y in rng.uniform(-5, 5, (25, 2))]
    parts.append(box((-6, 5, 0), (6, 5.5, 4)))             # a back wall
    mesh_object("Props", *merge(parts))
    _camera(scene, (0.0, -12.0, 5.0), (0.0, 0.0, 0.5), fov_deg=55.0, near=0.5, far=40.0)
    _spot(scene, (-3.0, -8.0, 10.0), (0.0, 0.0, 0.0), 60.0)
    return scene


def point_behind_camera():
    """A point light 4 m behind and 3 m above the camera over a block of boxes."""
    scene = reset()
    _city(seed=11, extent=40.0, count=120)
    _camera(scene, (0.0, -30.0, 3.0), (0.0, 0.0, 0.0), fov_deg=60.0, near=0.1, far=80.0)
    _point(scene, (1.0, -34.0, 6.0))
    return scene


def point_low_in_view():
    """A point light 1.5 m above the ground among the boxes, in the camera's view."""
    scene = reset()
    _city(seed=13, extent=40.0, count=120)
    _camera(scene, (0.0, -30.0, 6.0), (0.0, 0.0, 0.0), fov_deg=60.0, near=0.1, far=80.0)
    _point(scene, (0.0, -10.0, 1.5))
    return scene


def contact():
    """Boxes standing on the ground under a sun 40° high: shadows must reach their feet."""
    scene = reset()
    mesh_object("Ground", *grid(np.linspace(-20, 20, 2), np.linspace(-20, 20, 2)))
    mesh_object("Boxes", *merge([box((-3, -1, 0), (-1, 1, 2)), box((1, 2, 0), (2, 3, 4)),
                                 box((2.5, -2, 0), (3.5, -1.5, 0.5))]))
    _camera(scene, (-6.0, -9.0, 5.0), (0.5, 0.0, 0.5), fov_deg=50.0, near=0.1, far=60.0)
    add_sun(scene, (0.5, 0.6, -math.tan(math.radians(40.0)) * math.hypot(0.5, 0.6)))
    return scene


BOX_SCENES = {
    "city_side_sun": city_side_sun,
    "city_behind_sun": city_behind_sun,
    "city_low_sun": city_low_sun,
    "forest_side_sun": forest_side_sun,
    "stage_spot": stage_spot,
    "point_behind_camera": point_behind_camera,
    "point_low_in_view": point_low_in_view,
    "contact": contact,
}
"""Box scenes by name; names starting with ``point_`` are the point-light scenes."""
