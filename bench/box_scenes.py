"""Box scenes for judging rendered shadows against exact ray casting.

Each builder starts from an empty file and makes a ground, boxes, one camera
(no animation) and one light, the kinds of configuration the rendered-shadows
issue names: a sun from the side, from behind, low over a city; a forest of
thin trees; a spot-lit stage; point lights behind the camera and low in the view;
a box standing on the ground (contact). Geometry is exact boxes, so the ray-cast
ground truth sees exactly what the rasteriser draws.

Generated scenes (:func:`draw_scene`, named by :func:`generated_name`) are more
of the same kinds drawn from a seed, scenes nobody tuned for: a town of random
buildings and trees, a random camera, and a light of each kind in turn
(:data:`GENERATED_KINDS`).

    from bench.box_scenes import BOX_SCENES, box_scene, generated_name
    scene = BOX_SCENES["city_side_sun"]()
    scene = box_scene(generated_name(seed=1, index=5))()    # "gen1_05_point_low_in_view"
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

import bpy
import numpy as np

from sample_blends.scenes import _aim, add_spot, add_sun, box, grid, merge, mesh_object, reset

SPOT_ENERGY = 20000.0
"""The box scenes' spot lights' energy (W), ten times ``add_spot``'s default."""


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


def _street_under_sun(direction):
    """The city seen down its open street (x = 0) from 80 m back, under a sun travelling along ``direction``."""
    scene = reset()
    _city()
    _camera(scene, (0.0, -80.0, 1.8), (0.0, 20.0, 0.0), fov_deg=60.0, near=0.1, far=150.0)
    add_sun(scene, direction)
    return scene


def city_side_sun():
    """A street view, the sun from the side (15° off perpendicular to the view, towards the
    camera, so the walls facing the camera are not exactly edge-on to it), 35° high."""
    return _street_under_sun((1.0, -0.27, -math.tan(math.radians(35.0)) * math.hypot(1.0, 0.27)))


def city_behind_sun():
    """A street view, the sun from behind the camera (30° high)."""
    return _street_under_sun((0.25, 1.0, -math.tan(math.radians(30.0))))


def city_low_sun():
    """A street view, a sun 8° above the horizon from the side and ahead."""
    return _street_under_sun((0.8, -0.6, -math.tan(math.radians(8.0))))


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
    add_spot(scene, (-3.0, -8.0, 10.0), (0.0, 0.0, 0.0), 60.0, energy=SPOT_ENERGY)
    return scene


def _block_under_point(seed, eye, lamp):
    """A block of 120 boxes (``seed``) seen from ``eye`` towards the origin, a point light at ``lamp``."""
    scene = reset()
    _city(seed=seed, extent=40.0, count=120)
    _camera(scene, eye, (0.0, 0.0, 0.0), fov_deg=60.0, near=0.1, far=80.0)
    _point(scene, lamp)
    return scene


def point_behind_camera():
    """A point light 4 m behind and 3 m above the camera over a block of boxes."""
    return _block_under_point(11, (0.0, -30.0, 3.0), (1.0, -34.0, 6.0))


def point_low_in_view():
    """A point light 1.5 m above the ground among the boxes, in the camera's view."""
    return _block_under_point(13, (0.0, -30.0, 6.0), (0.0, -10.0, 1.5))


def contact():
    """Boxes standing on the ground under a sun 40° high: shadows must reach their feet."""
    scene = reset()
    mesh_object("Ground", *grid(np.linspace(-20, 20, 2), np.linspace(-20, 20, 2)))
    mesh_object("Boxes", *merge([box((-3, -1, 0), (-1, 1, 2)), box((1, 2, 0), (2, 3, 4)),
                                 box((2.5, -2, 0), (3.5, -1.5, 0.5))]))
    _camera(scene, (-6.0, -9.0, 5.0), (0.5, 0.0, 0.5), fov_deg=50.0, near=0.1, far=60.0)
    add_sun(scene, (0.5, 0.6, -math.tan(math.radians(40.0)) * math.hypot(0.5, 0.6)))
    return scene


# ---------------------------------------------------------------- generated scenes

GENERATED_KINDS = ("side_sun", "behind_sun", "low_sun", "spot", "point_behind_camera", "point_low_in_view")
"""The light of generated scene k is ``GENERATED_KINDS[k % 6]``, relative to the camera's view
direction: a sun from the side, from behind, low (3-10 degrees); a spot from above ahead; a point
light behind the camera, and one low in the view (the rendered-shadows issue's configurations)."""


@dataclass(frozen=True)
class GeneratedScene:
    """One drawn box scene, plain data (:func:`draw_scene`); :func:`build_generated` makes it in Blender."""
    kind: str                       # one of GENERATED_KINDS
    ground: float                   # the ground is the square [-ground, ground]^2 at z = 0
    boxes: np.ndarray               # (n, 2, 3) lower and upper corners, world metres
    camera: np.ndarray              # (2, 3) location and a point it looks at
    fov_deg: float                  # horizontal
    near: float
    far: float
    light: np.ndarray               # sun: the direction its light travels; spot, point: location
    target: np.ndarray | None = None   # spot: the point it is aimed at
    cone_deg: float = 0.0              # spot: full cone angle


def _town(rng, ground: float) -> np.ndarray:
    """Buildings (0.5-15 m high) and trees (a trunk and a crown box), 0.005-0.04 of them per square
    metre of the ground, (n, 2, 3)."""
    out = []
    for _ in range(int(rng.uniform(0.005, 0.04) * (1.8 * ground) ** 2)):
        c = rng.uniform(-0.9 * ground, 0.9 * ground, 2)
        if rng.random() < 0.6:
            s, h = rng.uniform(0.4, 4.0, 2), rng.uniform(0.5, 15.0)
            out.append([[*(c - s), 0.0], [*(c + s), h]])
        else:
            h, r = rng.uniform(2.0, 8.0), rng.uniform(0.5, 1.5)
            out += [[[*(c - 0.15), 0.0], [*(c + 0.15), 0.4 * h]], [[*(c - r), 0.4 * h], [*(c + r), h]]]
    return np.array(out)


def _clear(boxes: np.ndarray, point, radius: float) -> np.ndarray:
    """The boxes whose footprint is farther than ``radius`` from ``point`` (xy)."""
    gap = np.maximum(np.maximum(boxes[:, 0, :2] - point[:2], point[:2] - boxes[:, 1, :2]), 0.0)
    return boxes[np.hypot(*gap.T) > radius]


def _clear_sight(boxes: np.ndarray, eye, point) -> np.ndarray:
    """The boxes that do not cut the segment from ``eye`` to ``point``."""
    from addon.warp.rays import first_hits, slab_intervals
    with np.errstate(divide="ignore"):
        enter, leave = slab_intervals(eye, 1.0 / (point - eye), boxes[:, 0], boxes[:, 1])
    return boxes[~np.isfinite(first_hits(enter, leave, 1.0))]


def _unit(azimuth: float, elevation: float) -> np.ndarray:
    """A unit vector at ``azimuth`` (about +z from +x) and ``elevation`` (up from the ground), radians."""
    return np.array([math.cos(azimuth) * math.cos(elevation), math.sin(azimuth) * math.cos(elevation),
                     math.sin(elevation)])


def _in_view(rng, eye, forward, fov_deg: float, far: float, height: float) -> np.ndarray:
    """A random point at ``height`` seen in the lower half of the view, within half the far distance."""
    side = np.cross(forward, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side)
    half = math.tan(math.radians(fov_deg) / 2)
    while True:                             # the eye is at most 10 m up: v = -0.5 always reaches
        ray = forward + half * (rng.uniform(-0.6, 0.6) * side + rng.uniform(-0.5, -0.05) * np.cross(side, forward))
        t = (height - eye[2]) / ray[2]
        if 0 < t * np.linalg.norm(ray) < 0.5 * far:
            return eye + t * ray


def draw_scene(seed: int, index: int) -> GeneratedScene:
    """Generated scene ``index`` of ``seed`` (its own random stream: the same whatever the count)."""
    rng = np.random.default_rng([seed, index])
    kind = GENERATED_KINDS[index % len(GENERATED_KINDS)]
    ground = rng.uniform(60.0, 150.0)
    boxes = _town(rng, ground)
    yaw, pitch = rng.uniform(0, 2 * math.pi), -math.radians(rng.uniform(3.0, 35.0))
    eye = np.array([*rng.uniform(-0.5 * ground, 0.5 * ground, 2), rng.uniform(1.5, 25.0)])
    forward = _unit(yaw, pitch)
    fov, near, far = rng.uniform(40.0, 80.0), float(rng.choice([0.05, 0.1, 0.5, 1.0])), rng.uniform(60.0, 250.0)
    boxes = _clear(boxes, eye, 3.0)
    light, target, cone = None, None, 0.0
    if kind.endswith("sun"):
        azimuth, elevation = {"side_sun": (yaw + rng.choice([-1, 1]) * math.radians(90 + rng.uniform(-25, 25)),
                                           rng.uniform(15, 55)),
                              "behind_sun": (yaw + math.radians(rng.uniform(-35, 35)), rng.uniform(15, 60)),
                              "low_sun": (rng.uniform(0, 2 * math.pi), rng.uniform(3, 10))}[kind]
        light = _unit(azimuth, -math.radians(elevation))
    elif kind == "point_behind_camera":
        light = eye - _unit(yaw, 0.0) * rng.uniform(2.0, 10.0) + np.array([*rng.uniform(-3, 3, 2), rng.uniform(1, 6)])
        boxes = _clear(boxes, light, 2.0)
    else:                   # aimed at, or a point 0.5-3 m above, a spot on the ground in the camera's sight
        eye[2] = np.clip(eye[2], 4.0, 10.0)
        target = _in_view(rng, eye, forward, fov, far, 0.0 if kind == "spot" else rng.uniform(0.5, 3.0))
        boxes = _clear_sight(boxes, eye, target)
        if kind == "spot":
            light = target + np.array([*rng.uniform(-15, 15, 2), rng.uniform(8.0, 25.0)])
            cone = rng.uniform(30.0, 100.0)
            boxes = _clear_sight(_clear(boxes, light, 2.0), light, target)
        else:
            light, target = target, None
            boxes = _clear(boxes, light, 2.0)
    return GeneratedScene(kind, ground, boxes, np.array([eye, eye + forward]), fov, near, far, light, target, cone)


def build_generated(g: GeneratedScene):
    """Build ``g`` (:func:`draw_scene`) in an empty file; returns the bpy scene."""
    scene = reset()
    mesh_object("Ground", *grid(np.linspace(-g.ground, g.ground, 2), np.linspace(-g.ground, g.ground, 2)))
    mesh_object("Boxes", *merge([box(lo, hi) for lo, hi in g.boxes]))
    _camera(scene, tuple(g.camera[0]), tuple(g.camera[1]), fov_deg=g.fov_deg, near=g.near, far=g.far)
    if g.kind.endswith("sun"):
        add_sun(scene, tuple(g.light))
    elif g.kind == "spot":
        add_spot(scene, tuple(g.light), tuple(g.target), g.cone_deg, energy=SPOT_ENERGY)
    else:
        _point(scene, tuple(g.light))
    return scene


def generated_name(seed: int, index: int) -> str:
    """``gen<seed>_<index>_<kind>``: :func:`box_scene` builds it again from the name alone."""
    return f"gen{seed}_{index:02d}_{GENERATED_KINDS[index % len(GENERATED_KINDS)]}"


def box_scene(name: str):
    """The builder of box scene ``name``: one of :data:`BOX_SCENES` or a :func:`generated_name`; None if neither."""
    drawn = re.fullmatch(r"gen(\d+)_(\d+)_(\w+)", name)
    if drawn and generated_name(int(drawn[1]), int(drawn[2])) == name:
        return lambda: build_generated(draw_scene(int(drawn[1]), int(drawn[2])))
    return BOX_SCENES.get(name)


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
