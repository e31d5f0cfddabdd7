"""plane_optimal's claims (Chong & Gortler, "A Lixel for every Pixel"), rendered
and judged against ray casting (``test_gpu_shadows``' helpers and truth):

* on the plane of interest every pixel samples exactly its own point, so its
  shadows there are the ray-cast ones (§2: "exactly one lixel ... samples the
  exact same geometric point"), with the default 3x3 PCF too: the plane map's
  one lixel is read unfiltered, and a larger budget refines the fallback;
* a box standing on the plane shadows it right up to its foot.
"""
import math

import numpy as np
import pytest

from test_gpu_shadows import aim, box, bvh_of, camera, light, lx, plane, ray_shadow, render, scene  # noqa: F401

RES = (320, 180)


def poles_scene(scene):
    """A 60 m ground with thin poles (4 cm) whose shadows, under a low side
    sun, are a pixel wide or less, seen from eye height."""
    plane(scene, size=60.0)
    for k, y in enumerate((3.0, 6.0, 9.0, 13.0, 18.0, 24.0)):
        box(scene, f"Pole{k}", size=(0.04, 0.04, 3.0), location=(-2.0 + 0.7 * k, y, 1.5))
    cam = camera(scene, (0.0, -4.0, 1.6), (0, 0, 0), res=RES)
    aim(cam, (0.0, 12.0, 0.0))
    sun = light(scene, "SUN", energy=3.0)
    sun.rotation_euler = (math.radians(65), 0, math.radians(-70))     # 25° above the horizon, from the side
    return sun


def contact_scene(scene, kind="SUN"):
    """A box standing on the ground, its shadow side towards the camera: under
    a sun 40° high, or under a point light beside it, lower than its top (so
    casters reach the light's height, where a plane map's z / w has its pole)."""
    plane(scene, size=30.0)
    box(scene, size=(1.0, 1.0, 2.0), location=(0.0, 0.0, 1.0), rotation=(0, 0, 0.3))
    cam = camera(scene, (3.0, -6.0, 3.5), (0, 0, 0), res=RES)
    aim(cam, (0.0, 0.5, 0.3))
    if kind == "POINT":
        return light(scene, "POINT", (-1.2, 2.5, 1.5), energy=800.0)
    sun = light(scene, "SUN", energy=3.0)
    sun.rotation_euler = (math.radians(50), 0, math.radians(150))     # 40° high, from behind the box
    return sun


def plane_pixels(lx, scene, map_size, planes=(), **shadow):
    """Render with plane_optimal (the ``planes`` given, else its default plane);
    the plane map's pixels with their rendered and ray-cast shadows, the world
    points and the setup."""
    options = lx.warp.WarpOptions(shadow_map_size=(map_size, map_size), planes=planes)
    out, view, lt, setup, dg = render(lx, scene, "plane_optimal", map_size, shadow=shadow or None,
                                      warp_options=options)
    index = np.asarray(out.map_index)
    roles = [m.role for m in setup.maps]
    assert roles[0] == "plane:0", setup.diagnostics.fallbacks
    on_plane = np.asarray(out.covered) & (index == 0)
    ys, xs = np.nonzero(on_plane)
    points = np.asarray(out.world_position)[ys, xs].astype(np.float64)
    truth = ray_shadow(bvh_of(dg), lt, points)
    got = np.asarray(out.shadow_mask)[ys, xs] > 0.5
    return got, truth, points, (ys, xs), setup


def lixels_per_pixel(setup):
    return setup.diagnostics.extra["budget"]["lixels_per_pixel"]


@pytest.mark.parametrize("map_size", [256, 1024, 4096])
@pytest.mark.parametrize("pcf", [1, 3])
def test_every_pixel_of_the_plane_samples_its_own_point(lx, scene, map_size, pcf):
    """At one lixel per pixel, whatever the budget, the plane map's shadows
    are the ray-cast ones at every pixel of the plane, thin pole shadows of a
    pixel or less included, with or without PCF; each pixel's point lies at
    the centre of its lixel; a larger budget only enlarges the fallback."""
    poles_scene(scene)
    got, truth, points, _, setup = plane_pixels(lx, scene, map_size, pcf_kernel=pcf)
    assert lixels_per_pixel(setup) == 1.0
    assert len(points) > 10000 and truth.sum() > 100
    wrong = int((got != truth).sum())
    assert wrong <= 2, f"{wrong} of {len(points)} plane pixels disagree with ray casting"
    m = setup.maps[0]
    h = np.column_stack([points, np.ones(len(points))]) @ m.matrix.T
    texel = (h[:, :2] / h[:, 3:4] + 1) / 2 * np.array(m.size)
    off_centre = np.abs(texel - np.floor(texel) - 0.5)
    assert np.percentile(off_centre, 99) < 0.02            # float32 positions: a few hundredths of a pixel
    fallback = setup.maps[-1].size
    assert fallback[0] * fallback[1] >= map_size * map_size - m.size[0] * m.size[1] - 2 * map_size


@pytest.mark.parametrize("kind,linear_z", [("SUN", False), ("SUN", True), ("POINT", True)])
def test_a_box_standing_on_the_plane_shadows_it_to_its_foot(lx, scene, kind, linear_z):
    """No light leaks between a caster and the plane it stands on: every plane
    pixel inside the box's true shadow is shadowed, right up to the foot (the
    box's own pixels do not count as the shadow's edge), and rendered shadows
    differ from ray casting only on the true shadow's edge (within a pixel,
    which is N >= 1 lixels of the plane map).

    The point light stores the linear height: a plane map's hyperbolic z / w
    = a - b·h / w has its pole where w = 0, at the light's height, so casters
    near it stretch the depth window and the constant bias spans metres of
    height on the plane (in the box scene point_low_in_view, 8,714 of the
    plane map's 83,009 pixels lit in shadow at 2048²; none with the height)."""
    contact_scene(scene, kind)
    options = lx.warp.WarpOptions(shadow_map_size=(2048, 2048), linear_z=linear_z)
    out, view, lt, setup, dg = render(lx, scene, "plane_optimal", 2048, warp_options=options)
    assert setup.maps[0].role == "plane:0"
    on_plane = np.asarray(out.covered) & (np.asarray(out.map_index) == 0)
    world = np.asarray(out.world_position)
    ys, xs = np.nonzero(on_plane)
    truth = np.zeros(on_plane.shape, dtype=bool)
    truth[ys, xs] = ray_shadow(bvh_of(dg), lt, world[ys, xs].astype(np.float64))
    got = np.asarray(out.shadow_mask) > 0.5
    inside = on_plane & truth & _all_plane_neighbours(truth, on_plane)
    outside = on_plane & ~truth & _all_plane_neighbours(~truth, on_plane)
    foot = inside & (np.nan_to_num(_distance_to_box(world), nan=1.0) < 0.05)
    assert foot.sum() > 10, "the box's shadow at its foot must be in view"
    assert not (inside & ~got).any(), f"{(inside & ~got).sum()} plane pixels lit inside the box's shadow"
    assert not (outside & got).any(), f"{(outside & got).sum()} plane pixels shadowed away from the shadow's edge"


def _all_plane_neighbours(mask, on_plane):
    """Pixels whose 8 neighbours that lie on the plane are all in ``mask``."""
    ok = np.ones_like(mask)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            shifted_mask = np.roll(np.roll(mask, dy, 0), dx, 1)
            shifted_plane = np.roll(np.roll(on_plane, dy, 0), dx, 1)
            ok &= shifted_mask | ~shifted_plane
    return ok


def _distance_to_box(world):
    """Horizontal distance of world points from the contact box's footprint (negative inside)."""
    c, s = math.cos(-0.3), math.sin(-0.3)
    x, y = world[..., 0], world[..., 1]
    u, v = c * x - s * y, s * x + c * y                      # into the box's frame (turned 0.3 rad)
    return np.maximum(np.abs(u), np.abs(v)) - 0.5


@pytest.mark.parametrize("map_size", [128, 160, 192])
def test_below_one_lixel_per_pixel_the_filter_reconstructs_the_plane(lx, scene, map_size):
    """Below one lixel per pixel (the paper's s < 1: a plane the user gives
    keeps the paper's budget; the default plane then gets no map) the plane's
    points fall between lixels, so no lixel's test is a pixel's exact shadow:
    the PCF kernel reconstructs the shadow between them as in any map, and
    fewer plane pixels are wrong with the default bilinear PCF 2 than with the
    nearest lixel (PCF 1). Where a point lies on its lixel's centre (one lixel
    per pixel) the lixel is read unfiltered (above)."""
    contact_scene(scene)
    ground = (((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)),)
    got, truth, points, _, setup = plane_pixels(lx, scene, map_size, planes=ground, pcf_kernel=2)
    nearest, _, _, _, _ = plane_pixels(lx, scene, map_size, planes=ground, pcf_kernel=1)
    assert lixels_per_pixel(setup) < 1.0
    filtered, unfiltered = int((got != truth).sum()), int((nearest != truth).sum())
    assert filtered < unfiltered, f"PCF 2 {filtered} vs nearest lixel {unfiltered} of {len(points)} plane pixels wrong"
