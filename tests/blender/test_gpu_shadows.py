"""The gpu pipeline draws shadows where ray casting says they are.

Ground truth is ``mathutils.bvhtree.BVHTree`` ray casting from each visible
surface point towards the light. Images are small (the camera), the shadow
maps are 2048² where the issue asks for it.
"""
import importlib
import math
from dataclasses import replace
from pathlib import Path

import bpy
import numpy as np
import pytest
from mathutils import Vector
from mathutils.bvhtree import BVHTree

from addon.measure.errors import shadow_edges
from addon.warp.methods import METHODS as _METHODS_AT_COLLECTION
from ui_scenes import build

METHOD_NAMES = sorted(_METHODS_AT_COLLECTION)


class Lx:
    """The extension's modules (imported through the enabled extension)."""

    def __init__(self, root):
        imp = lambda name: importlib.import_module(f"{root.__name__}.{name}")  # noqa: E731
        self.context = imp("addon.gpu.context")
        self.pipeline = imp("addon.gpu.pipeline")
        self.batches = imp("addon.gpu.batches")
        self.result = imp("addon.gpu.result")
        self.compose = imp("addon.gpu.compose")
        self.targets = imp("addon.gpu.targets")
        self.culling = imp("addon.warp.culling")
        self.describe = imp("addon.scene.describe")
        self.geometry = imp("addon.scene.geometry")
        self.warp = imp("addon.warp")
        self.wgeom = imp("addon.warp.geometry")
        self.types = imp("addon.warp.types")
        self.settings = imp("addon.settings")


@pytest.fixture(scope="module")
def lx(lixel):
    m = Lx(lixel)
    m.context.ensure_gpu_context()
    return m


@pytest.fixture
def scene(fresh_scene):
    """An empty scene; the objects and data made in it are removed afterwards."""
    yield fresh_scene


def named(scene, prefix):
    return next(o for o in scene.objects if o.name.startswith(prefix))


# ---------------------------------------------------------------- scene building

def link(scene, ob):
    scene.collection.objects.link(ob)
    return ob


def mesh_object(scene, name, verts, faces, location=(0, 0, 0), rotation=(0, 0, 0)):
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(v) for v in verts], [], [tuple(f) for f in faces])
    me.update()
    ob = link(scene, bpy.data.objects.new(name, me))
    ob.location = location
    ob.rotation_euler = rotation
    return ob


def plane(scene, name="Ground", size=10.0, location=(0, 0, 0), rotation=(0, 0, 0)):
    h = size / 2
    return mesh_object(scene, name, [(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)], [(0, 1, 2, 3)],
                       location, rotation)


def box(scene, name="Box", size=(1, 1, 1), location=(0, 0, 1), rotation=(0, 0, 0)):
    sx, sy, sz = (s / 2 for s in size)
    verts = [(x, y, z) for x in (-sx, sx) for y in (-sy, sy) for z in (-sz, sz)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return mesh_object(scene, name, verts, faces, location, rotation)


def camera(scene, location, rotation, res=(160, 160), lens=35.0, ortho_scale=None):
    cam = bpy.data.cameras.new("Cam")
    cam.lens = lens
    cam.clip_start, cam.clip_end = 0.1, 100.0
    if ortho_scale is not None:
        cam.type = "ORTHO"
        cam.ortho_scale = ortho_scale
    ob = link(scene, bpy.data.objects.new("Cam", cam))
    ob.location, ob.rotation_euler = location, rotation
    scene.camera = ob
    scene.render.resolution_x, scene.render.resolution_y = res
    scene.render.resolution_percentage = 100
    return ob


def light(scene, kind, location=(0, 0, 10), rotation=(0, 0, 0), **data):
    lt = bpy.data.lights.new(kind.title(), kind)
    for k, v in data.items():
        setattr(lt, k, v)
    ob = link(scene, bpy.data.objects.new(kind.title(), lt))
    ob.location, ob.rotation_euler = location, rotation
    return ob


def aim(ob, target):
    d = Vector(target) - ob.location
    ob.rotation_euler = d.to_track_quat("-Z", "Y").to_euler()


def shadow_scene(scene, kind):
    """A 10 m ground with a 1 m box hovering over it, seen obliquely, lit by a sun or a spot."""
    plane(scene)
    box(scene, size=(2.0, 1.6, 1.0), location=(0.3, -0.2, 1.3), rotation=(0, 0, 0.4))
    cam = camera(scene, (0, -7, 6), (0, 0, 0))
    aim(cam, (0, 0, 0))
    if kind == "SUN":
        lt = light(scene, "SUN", (0, 0, 10), energy=3.0)
        lt.rotation_euler = (math.radians(35), 0, math.radians(25))
    elif kind == "POINT":
        lt = light(scene, "POINT", (2.0, -1.0, 4.5), energy=800.0)
    else:
        lt = light(scene, "SPOT", (2.5, -1.5, 6.0), spot_size=math.radians(70), energy=800.0)
        aim(lt, (0, 0, 0))
    return lt


def render(lx, scene, method="uniform", map_size=2048, shadow=None, setup=None, gpu_scene=None, warp_options=None,
           **kwargs):
    dg = scene.view_layers[0].depsgraph
    dg.update()
    geometry = lx.geometry.GeometryCache().update(dg)
    view, lt, bounds = lx.describe.describe_scene(scene, dg, instances=geometry.instances)
    options = warp_options or lx.warp.WarpOptions(shadow_map_size=(map_size, map_size))
    if setup is None:
        setup = lx.warp.compute(method, view, lt, bounds, options)
    settings = lx.settings.LixelSettings(method=method, warp=options)
    if shadow is not None:
        settings = replace(settings, shadow=replace(settings.shadow, **shadow))
    out = lx.pipeline.render_shadows(view, lt, setup, geometry, settings,
                                     scene=gpu_scene or lx.batches.GPUScene(), read=lx.result.EVERYTHING, **kwargs)
    return out, view, lt, setup, dg


def cached_frame(lx, scene, geometry_cache, gpu_scene, method, **kwargs):
    """(the pipeline's output, the geometry, the bounds) of a frame drawn as the engine draws one after another:
    through a kept ``GeometryCache`` and ``GPUScene``, 256² maps."""
    dg = scene.view_layers[0].depsgraph
    dg.update()
    geometry = geometry_cache.update(dg)
    view, lt, bounds = lx.describe.describe_scene(scene, dg, instances=geometry.instances)
    setup = lx.warp.compute(method, view, lt, bounds, lx.warp.WarpOptions(shadow_map_size=(256, 256)))
    return lx.pipeline.render_shadows(view, lt, setup, geometry, scene=gpu_scene, **kwargs), geometry, bounds


# ---------------------------------------------------------------- ground truth

def bvh_of(dg):
    verts, polys = [], []
    for inst in dg.object_instances:
        ob = inst.object
        if ob.type != "MESH":
            continue
        m = inst.matrix_world.copy()
        base = len(verts)
        verts += [tuple(m @ v.co) for v in ob.data.vertices]
        polys += [tuple(base + i for i in p.vertices) for p in ob.data.polygons]
    return BVHTree.FromPolygons(verts, polys)


def ray_shadow(bvh, lt, points, normals_hint=None):
    """True where the segment from a point towards the light hits geometry."""
    out = np.zeros(len(points), dtype=bool)
    for i, p in enumerate(points):
        p = Vector(p.tolist())
        if lt.type == "SUN":
            d = Vector((-lt.direction).tolist())
            dist = 1e4
        else:
            d = Vector(lt.position.tolist()) - p
            dist = d.length
            d.normalize()
        start = p + d * 1e-3
        hit = bvh.ray_cast(start, d, dist - 2e-3)
        out[i] = hit[0] is not None
    return out


def edge_band(truth_img, covered, radius_px):
    """Pixels within ``radius_px`` (per pixel) of a pixel whose truth differs from a neighbour's."""
    t = np.where(covered, truth_img, False)
    edge = np.zeros_like(t)
    edge[:-1] |= (t[:-1] != t[1:]) & covered[:-1] & covered[1:]
    edge[1:] |= (t[:-1] != t[1:]) & covered[:-1] & covered[1:]
    edge[:, :-1] |= (t[:, :-1] != t[:, 1:]) & covered[:, :-1] & covered[:, 1:]
    edge[:, 1:] |= (t[:, :-1] != t[:, 1:]) & covered[:, :-1] & covered[:, 1:]
    ey, ex = np.nonzero(edge)
    band = np.zeros_like(t)
    if len(ey) == 0:
        return band
    ys, xs = np.nonzero(covered)
    e = np.stack([ey, ex], 1).astype(np.float64)
    for start in range(0, len(ys), 4096):
        p = np.stack([ys[start:start + 4096], xs[start:start + 4096]], 1).astype(np.float64)
        d = np.sqrt(((p[:, None, :] - e[None, :, :]) ** 2).sum(-1)).min(1)
        r = radius_px[ys[start:start + 4096], xs[start:start + 4096]]
        band[ys[start:start + 4096], xs[start:start + 4096]] = d <= r
    return band


def agreement(out, lt, dg, texels=2.0):
    """(fraction of compared pixels whose shadow agrees with ray casting, compared count)."""
    covered = out.covered & (out.map_index >= 0)
    ys, xs = np.nonzero(covered)
    pts = out.world_position[ys, xs].astype(np.float64)
    truth = np.zeros(covered.shape, dtype=bool)
    truth[ys, xs] = ray_shadow(bvh_of(dg), lt, pts)
    tpp = np.maximum(out.texels_per_pixel, 1e-6)
    band = edge_band(truth, covered, texels / tpp + 1.5)
    compare = covered & ~band
    got = out.shadow_mask > 0.5
    ok = (got == truth) & compare
    return ok.sum() / max(compare.sum(), 1), int(compare.sum()), truth


# ---------------------------------------------------------------- tests

def test_the_frame_says_which_face_each_pixel_shows(lx, scene):
    """world_normal is the geometric normal of the face each pixel shows (the pre-pass's, read with the position),
    within its packing and derivatives' error, and NaN where nothing is seen: what tells a judge that the
    rasterizer and a ray caster saw one point on two faces of a box."""
    shadow_scene(scene, "SUN")
    out, *_ = render(lx, scene, "uniform", 512)
    c, s = math.cos(0.4), math.sin(0.4)
    faces = np.array([[0, 0, 1], [c, s, 0], [-s, c, 0]], dtype=np.float64)   # ground and box tops, the box's sides
    n = out.world_normal[out.covered]
    assert len(n) > 5000 and np.all(np.isnan(out.world_normal[~out.covered]))
    angle = np.arccos(np.clip(np.abs(n @ faces.T).max(axis=1), 0.0, 1.0))
    assert angle.max() < 1e-3
    ground = out.covered & (np.abs(out.world_position[..., 2]) < 1e-4)
    assert np.all(np.abs(out.world_normal[ground][:, 2]) > math.cos(1e-3))


@pytest.mark.parametrize("kind", ["SUN", "SPOT", "POINT"])
@pytest.mark.parametrize("method", METHOD_NAMES)
def test_shadows_agree_with_ray_casting(lx, scene, kind, method):
    lt = shadow_scene(scene, kind)
    if method not in lx.warp.METHODS:
        pytest.fail(f"method {method} vanished from METHODS")
    out, view, light_, setup, dg = render(lx, scene, method, 2048)
    frac, n, truth = agreement(out, light_, dg)
    assert n > 5000, "too few pixels compared: the scene is not in view"
    assert truth[out.covered].mean() > 0.02, "the test scene must contain shadow"
    assert frac >= 0.99, f"{method}/{kind}: only {frac:.4f} of {n} pixels agree with ray casting"
    c = out.counts
    assert c.casters_drawn == 2 and c.caster_triangles_drawn == 2 + 12


def test_shadow_is_lambert_lit_in_light_colour(lx, scene):
    lt = shadow_scene(scene, "SUN")
    lt.data.color = (1.0, 0.5, 0.25)
    out, view, light_, setup, dg = render(lx, scene, "uniform", 512)
    ground = out.covered & (np.abs(out.world_position[..., 2]) < 1e-3) & (out.shadow_mask == 0)
    ndl = -light_.direction[2]  # ground normal is +Z
    expect = 0.8 * 3.0 * ndl / math.pi * np.array([1.0, 0.5, 0.25]) + 0.8 * np.array(lx.pipeline.DEFAULT_AMBIENT)
    got = out.combined[ground][:, :3].mean(axis=0)
    np.testing.assert_allclose(got, expect, rtol=1e-3, atol=1e-4)
    shadowed = out.covered & (np.abs(out.world_position[..., 2]) < 1e-3) & (out.shadow_mask == 1)
    assert shadowed.any()
    np.testing.assert_allclose(out.combined[shadowed][:, :3].mean(axis=0),
                               0.8 * np.array(lx.pipeline.DEFAULT_AMBIENT), atol=1e-4)


def test_point_light_irradiance_falls_with_distance_squared(lx, scene):
    plane(scene)
    cam = camera(scene, (0, -7, 6), (0, 0, 0))
    aim(cam, (0, 0, 0))
    light(scene, "POINT", (1.0, 0.5, 3.0), energy=500.0)
    out, view, lt, setup, dg = render(lx, scene, "uniform", 256)
    sel = out.covered & (out.shadow_mask == 0)
    p = out.world_position[sel].astype(np.float64)
    to_light = lt.position - p
    r2 = (to_light ** 2).sum(1)
    ndl = to_light[:, 2] / np.sqrt(r2)
    expect = 0.8 * 500.0 / (4 * math.pi * r2) * ndl / math.pi + 0.8 * lx.pipeline.DEFAULT_AMBIENT[0]
    np.testing.assert_allclose(out.combined[sel][:, 0], expect, rtol=2e-3, atol=1e-5)


@pytest.mark.parametrize("blend", [0.0, 0.4])
def test_spot_cone_follows_blenders_spot_mask(lx, scene, blend):
    plane(scene, size=12)
    cam = camera(scene, (0, 0, 12), (0, 0, 0), res=(128, 128), ortho_scale=12.0)
    spot = light(scene, "SPOT", (0, 0, 4), spot_size=math.radians(80), energy=1000.0)
    out, view, lt, setup, dg = render(lx, scene, "uniform", 512, spot_blend=blend)
    sel = out.covered
    p = out.world_position[sel].astype(np.float64)
    to_light = lt.position - p
    r2 = (to_light ** 2).sum(1)
    cos_angle = to_light[:, 2] / np.sqrt(r2)        # the spot points straight down; the ground normal is +Z
    cos_half = math.cos(math.radians(40))
    x = cos_angle - cos_half
    if blend:
        t = np.clip(x / (blend * (1 - cos_half)), 0, 1)
        mask = t * t * (3 - 2 * t)
    else:
        mask = (x >= 0).astype(np.float64)
    expect = 0.8 * 1000.0 / (4 * math.pi * r2) * cos_angle * mask / math.pi + 0.8 * lx.pipeline.DEFAULT_AMBIENT[0]
    away = np.abs(x) > 2e-3  # pixels straddling a hard edge may go either way
    np.testing.assert_allclose(out.combined[sel][:, 0][away], expect[away], rtol=2e-3, atol=2e-5)
    assert (mask == 0).any() and (mask == 1).any() and (blend == 0 or ((mask > 0) & (mask < 1)).any())


@pytest.mark.parametrize("kind, method", [("SUN", "uniform"), ("SUN", "lispsm"), ("POINT", "uniform"),
                                          ("SPOT", "lispsm")])
def test_a_linear_map_stores_its_depth_row(lx, scene, kind, method):
    """Scherzer §4.2's linear z, as the depth pass writes it (in place of an
    affine map's z row, or per fragment for a projective one): at every texel
    whose light ray reaches the ground unblocked, the stored depth is the depth
    row at the point where that ray meets the ground, and nowhere is it further."""
    shadow_scene(scene, kind)
    out, view, lt, setup, dg = render(lx, scene, method, 512)
    assert lx.pipeline.is_affine(setup.maps[0].matrix) == (kind == "SUN" and method == "uniform")
    compared = 0
    for m, stored in zip(setup.maps, out.shadow_maps):
        assert m.depth_row is not None
        h, w = stored.shape
        x, y = np.meshgrid((np.arange(w) + 0.5) / w * 2 - 1, (np.arange(h) + 0.5) / h * 2 - 1)
        inv = np.linalg.inv(m.matrix)
        ends = [np.stack([x, y, np.full_like(x, z), np.ones_like(x)], -1) @ inv.T for z in (-1.0, 1.0)]
        a, b = (e[..., :3] / e[..., 3:] for e in ends)
        t = a[..., 2] / (a[..., 2] - b[..., 2])                  # where the texel's light ray meets z = 0
        ground = a + t[..., None] * (b - a)
        on = (t >= 0) & (t <= 1) & (np.abs(ground[..., :2]) <= 4.9).all(-1)   # (off the ground's rim)
        expected = 0.5 * (np.c_[ground[on], np.ones(on.sum())] @ m.depth_row) + 0.5
        got = stored[on]
        compared += len(got)
        if len(got):
            assert (got <= expected + 1e-5).all(), m.role
            assert (np.abs(got - expected) < 1e-5).mean() > 0.8, m.role
    assert compared > 10000


def acne_scene(scene, closed=False, kind="SUN"):
    """A plane (or a 20 cm slab) whose normal is 80° from a straight-down sun
    (or from a point light high above it)."""
    if closed:
        box(scene, "Tilted", size=(6, 6, 0.2), location=(0, 0, 0), rotation=(math.radians(80), 0, 0))
    else:
        plane(scene, "Tilted", size=6, rotation=(math.radians(80), 0, 0))
    cam = camera(scene, (0, -9, 3), (0, 0, 0), res=(128, 128))
    aim(cam, (0, 0, 0))
    if kind == "SUN":
        light(scene, "SUN", (0, 0, 10), energy=2.0)
    else:
        light(scene, kind, (0, 0, 30), energy=20000.0, **({"spot_size": math.radians(60)} if kind == "SPOT" else {}))


def acne_fraction(out):
    lit_side = out.covered
    return float((out.shadow_mask[lit_side] > 0).mean())


@pytest.mark.parametrize("kind", ["SUN", "POINT"])
@pytest.mark.parametrize("method", METHOD_NAMES)
def test_a_plane_tilted_80_degrees_from_the_light_shows_no_acne(lx, scene, method, kind):
    """With every method's defaults (linear depth, receiver-plane bias in texels)."""
    acne_scene(scene, kind=kind)
    out, view, lt, setup, dg = render(lx, scene, method, 2048)
    assert out.covered.mean() > 0.2
    assert acne_fraction(out) == 0.0, f"{method}/{kind}: acne on {acne_fraction(out):.4f} of the plane"


@pytest.mark.parametrize("linear", [True, False])
def test_every_bias_mode_removes_acne_on_a_plane_80_degrees_from_the_light(lx, scene, linear):
    """NONE shows acne; every other mode, in texels of the receiver, removes it,
    for linear and hyperbolic depth and every PCF kernel (odd: a box; even: bilinear taps)."""
    acne_scene(scene)
    opts = lx.warp.WarpOptions(shadow_map_size=(1024, 1024), linear_z=linear)
    none, *_ = render(lx, scene, "uniform", warp_options=opts, shadow=dict(bias_mode="NONE", pcf_kernel=1))
    assert acne_fraction(none) > 0.2, "without bias the tilted plane must show acne"
    for mode in ("RECEIVER_PLANE", "NORMAL_OFFSET", "CONSTANT_SLOPE", "SLOPE"):
        for k in (1, 2, 3, 4, 5):
            out, *_ = render(lx, scene, "uniform", warp_options=opts, shadow=dict(bias_mode=mode, pcf_kernel=k))
            assert acne_fraction(out) < 0.005, f"{mode} k={k}: acne left"
    # tan 80° = 5.7 texels of depth per texel across the plane: a constant bias must exceed it
    const, *_ = render(lx, scene, "uniform", warp_options=opts, shadow=dict(bias_mode="CONSTANT", constant_bias=8.0,
                                                                           pcf_kernel=1))
    assert acne_fraction(const) < 0.005, "a large enough constant bias removes acne too"


def test_linear_z_with_slope_bias_removes_acne(lx, scene):
    acne_scene(scene)
    # (B over the whole view: fitted to the visible plane only, linear z leaves less acne to remove)
    opts = lx.warp.WarpOptions(shadow_map_size=(1024, 1024), linear_z=True, focus="view")
    out, view, lt, setup, dg = render(lx, scene, "lispsm" if "lispsm" in lx.warp.METHODS else "uniform",
                                      warp_options=opts, shadow=dict(bias_mode="NONE", pcf_kernel=1))
    assert setup.maps[0].depth_row is not None
    assert acne_fraction(out) > 0.2
    out, *_ = render(lx, scene, "lispsm" if "lispsm" in lx.warp.METHODS else "uniform",
                     warp_options=opts, shadow=dict(bias_mode="SLOPE", pcf_kernel=3))
    assert acne_fraction(out) < 0.005


FEET = ((0.0, 0.0, 0.5, 0.5), (-1.4, 0.0, 0.6, 0.02))
"""The boxes standing in contact_scene: (x, y, half-width in x, half-width in y) of each base."""


def contact_scene(scene, kind):
    """A 1 m box and a 4 cm thick slab standing on a 12 m ground, the camera
    5 m away looking at their feet on the side their shadows fall, a sun 35°
    high (or a point or spot light 4 m up, off to the side). The slab is
    thinner than a 512² map's texels are wide here: a bias of a few
    texels lifts its shadow off its foot."""
    plane(scene, size=12)
    for x, y, hx, hy in FEET:
        box(scene, size=(2 * hx, 2 * hy, 1.0), location=(x, y, 0.5))
    cam = camera(scene, (0.5, 4.0, 2.5), (0, 0, 0), res=(192, 192))
    aim(cam, (-0.8, 0.9, 0.2))
    if kind == "SUN":
        lt = light(scene, "SUN", (0, 0, 10), energy=3.0)
        lt.rotation_euler = (math.radians(55), 0, math.radians(20))
    elif kind == "POINT":
        lt = light(scene, "POINT", (-1.5, -2.5, 4.0), energy=2000.0)
    else:
        lt = light(scene, "SPOT", (-1.5, -2.5, 4.0), spot_size=math.radians(80), energy=2000.0)
        aim(lt, (0.5, 0.8, 0))
    return lt


def ground_texel(setup, index, points):
    """The world size on the ground (z = 0) of one texel of the map serving
    each point: the longest side of the texel's image on the ground plane."""
    out = np.zeros(len(points))
    for i, m in enumerate(setup.maps):
        sel = index == i
        if not sel.any():
            continue
        p = points[sel]
        eps = 1e-4

        def ndc(q):
            h = np.c_[q, np.ones(len(q))] @ m.matrix.T
            return h[:, :2] / h[:, 3:]

        base = ndc(p)
        jx = (ndc(p + [eps, 0, 0]) - base) / eps
        jy = (ndc(p + [0, eps, 0]) - base) / eps
        jac = np.stack([jx, jy], axis=2)                           # d ndc / d ground, (n, 2, 2)
        inv = np.linalg.inv(jac)
        out[sel] = np.linalg.norm(inv, ord=2, axis=(1, 2)) * 2.0 / min(m.size)
    return out


_TRUTH: dict = {}
"""Ray-cast shadows of the contact scene's ground pixels, per light and pixel positions."""


def foot_contact(out, lt, dg, setup):
    """Ground pixels whose rendered shadow disagrees with ray casting although
    they are more than 2 texels of their map from every true shadow edge on the
    ground and from the box's foot: (false light, false shadow) counts, and the
    number of true-shadow ground pixels within 30 cm of a foot that were judged."""
    covered = out.covered & (out.map_index >= 0)
    world = out.world_position
    ground = covered & (np.abs(world[..., 2]) < 1e-3)
    ys, xs = np.nonzero(ground)
    pts = world[ys, xs].astype(np.float64)
    key = (lt.type, hash(pts.tobytes()))          # the camera pass does not depend on the maps
    if key not in _TRUTH:
        _TRUTH[key] = ray_shadow(bvh_of(dg), lt, pts)
    truth = _TRUTH[key]
    tau = ground_texel(setup, out.map_index[ys, xs], pts)
    img = np.zeros(covered.shape, dtype=bool)
    img[ys, xs] = truth
    on = np.zeros(covered.shape, dtype=bool)
    on[ys, xs] = True
    edge = shadow_edges(img, on)    # true shadow edges on the ground: shadowed pixels next to lit ones, and vice versa
    e = world[edge].astype(np.float64)
    d_edge = np.full(len(pts), np.inf)
    for start in range(0, len(pts), 2048):
        chunk = pts[start:start + 2048]
        if len(e):
            d_edge[start:start + 2048] = np.sqrt(((chunk[:, None, :2] - e[None, :, :2]) ** 2).sum(-1)).min(1)
    # Distance to the boxes' feet (their base rectangles).
    d_foot = np.min([np.hypot(np.maximum(np.abs(pts[:, 0] - x) - hx, 0.0), np.maximum(np.abs(pts[:, 1] - y) - hy, 0.0))
                     for x, y, hx, hy in FEET], axis=0)
    judged = (d_edge > 2 * tau) & (d_foot > 2 * tau)
    got = out.shadow_mask[ys, xs] >= 0.5
    near_foot = judged & truth & (d_foot < 0.3)
    return int((judged & truth & ~got).sum()), int((judged & ~truth & got).sum()), int(near_foot.sum())


@pytest.mark.parametrize("kind", ["SUN", "POINT", "SPOT"])
@pytest.mark.parametrize("method", METHOD_NAMES)
def test_a_box_standing_on_the_ground_shadows_it_up_to_its_foot_within_2_texels(lx, scene, method, kind):
    """With every method's defaults: no light leaks under a box's foot (a cube's
    and a slab's thinner than a texel at 512²) and no false shadow beyond 2
    texels of the true shadow's edges, at 512² (texels wider than pixels) and
    2048²."""
    lt = contact_scene(scene, kind)
    for size in (512, 2048):
        out, view, light_, setup, dg = render(lx, scene, method, size)
        leaks, false_shadow, judged = foot_contact(out, light_, dg, setup)
        assert judged > 50, f"{method}/{kind} {size}: the view must show the shadows at the feet"
        assert leaks == 0, f"{method}/{kind} {size}: {leaks} ground pixels lit more than 2 texels from the foot"
        assert false_shadow == 0, f"{method}/{kind} {size}: {false_shadow} ground pixels falsely shadowed"


def test_the_foot_judge_sees_peter_panning_and_acne(lx, scene):
    """The contact test can fail: a bias of 20 texels lifts the slab's shadow
    off its foot (light leaks under it) and no bias at all gives acne."""
    lt = contact_scene(scene, "SUN")
    out, view, light_, setup, dg = render(lx, scene, "uniform", 512, shadow=dict(bias_mode="CONSTANT",
                                                                                 constant_bias=20.0))
    leaks, _, _ = foot_contact(out, light_, dg, setup)
    assert leaks > 20
    out, view, light_, setup, dg = render(lx, scene, "uniform", 512, shadow=dict(bias_mode="NONE"))
    _, false_shadow, _ = foot_contact(out, light_, dg, setup)
    assert false_shadow > 20


def test_back_face_rendering_removes_acne_on_a_closed_slab(lx, scene):
    acne_scene(scene, closed=True)
    out, *_ = render(lx, scene, "uniform", 1024, shadow=dict(bias_mode="NONE", pcf_kernel=1))
    front = acne_fraction(out)
    out, *_ = render(lx, scene, "uniform", 1024, shadow=dict(bias_mode="NONE", pcf_kernel=1, back_faces=True))
    assert front > 0.2 and acne_fraction(out) < 0.005


@pytest.mark.parametrize("variant", ["GREATER", "MIRRORED"])
def test_reversed_and_mirrored_maps_cull_the_right_faces(lx, scene, variant):
    """A reversed depth test (clear 0, GREATER) or a map that mirrors x gives the
    same shadows as the plain map, and back-face rendering still culls the faces
    that face the light (no acne without bias on a closed slab)."""
    acne_scene(scene, closed=True)
    dg = scene.view_layers[0].depsgraph
    dg.update()
    view, lt, bounds = lx.describe.describe_scene(scene, dg)
    plain = lx.warp.compute("uniform", view, lt, bounds, lx.warp.WarpOptions(shadow_map_size=(1024, 1024)))
    m = plain.maps[0]
    flip = np.diag([1.0, 1.0, -1.0, 1.0]) if variant == "GREATER" else np.diag([-1.0, 1.0, 1.0, 1.0])
    other = lx.types.ShadowMap(flip @ m.matrix, m.size, "GREATER" if variant == "GREATER" else "LESS", m.role)
    setup = lx.types.ShadowSetup([other], plain.diagnostics)
    shadow = dict(bias_mode="NONE", pcf_kernel=1, back_faces=True)
    ref, *_ = render(lx, scene, setup=plain, shadow=shadow)
    out, *_ = render(lx, scene, setup=setup, shadow=shadow)
    assert acne_fraction(ref) < 0.005 and acne_fraction(out) < 0.005
    out, *_ = render(lx, scene, setup=setup, shadow=dict(bias_mode="NONE", pcf_kernel=1))
    assert acne_fraction(out) > 0.2, "drawing the light-facing faces (no culling) must show acne"
    ref, *_ = render(lx, scene, setup=plain, shadow=dict(bias_mode="NONE", pcf_kernel=1))
    if variant == "GREATER":  # z negated: the GREATER test must keep the same (nearest) surface
        np.testing.assert_allclose(out.shadow_maps[0], 1.0 - ref.shadow_maps[0], atol=1e-5)
    else:
        np.testing.assert_allclose(out.shadow_maps[0], ref.shadow_maps[0][:, ::-1], atol=1e-5)


NEAR_LIGHT_FACE = np.array([   # gen42_05_point_low_in_view's cascade at 4096²: a face's near plane 1e-7 of its far
    [-1.0467169022522258, -1.3421287933913522, -1.4812015034786026, 25.287431016058136],
    [1.2516409149264895, 0.8713215271319347, -1.721015304255863, -15.057608352104673],
    [-0.6628267683634359, 0.7397357805354811, -0.11597952464365072, -1.6053130791977437],
    [-0.6628269009287895, 0.739735928482637, -0.11597954783955564, -1.6053134002603584]])


@pytest.mark.parametrize("variant", ["LESS", "GREATER", "MIRRORED"])
def test_a_face_whose_near_plane_nearly_meets_the_light_winds_as_its_xyw_rows_say(lx, variant):
    """A point light's face with its near plane 1e-7 of the way to its far one has a z row equal to its w row to 7
    digits (condition 3e16): the render stopped there ("cannot normalize vector [nan, nan, nan]") where the winding
    test unprojected through the inverse. Its light-facing triangles wind as the same face's with a near plane
    farther out (z = w - 2 w_n: the same x, y and w rows), reversed or mirrored alike."""
    flip = {"LESS": np.eye(4), "GREATER": np.diag([1.0, 1.0, -1.0, 1.0]), "MIRRORED": np.diag([-1.0, 1.0, 1.0, 1.0])}
    test = "GREATER" if variant == "GREATER" else "LESS"
    winds = lambda m: lx.pipeline.light_facing_winds_clockwise(lx.types.ShadowMap(flip[variant] @ m, (4096, 4096), test))
    m = NEAR_LIGHT_FACE
    farther = [np.vstack([m[:2], m[3] - [0.0, 0.0, 0.0, 2.0 * w_n], m[3]]) for w_n in (1e-2, 1e-1, 1.0)]
    assert {winds(m) for m in farther} == {winds(NEAR_LIGHT_FACE)} == {variant == "MIRRORED"}


def light_facing_winding_judged_at(matrix, depth_test) -> set:
    """Whether a light-facing triangle winds clockwise, judged apart from ``light_facing_winds_clockwise``: tiny
    triangles (1e-6 of their distance from the world origin wide) at points the map sees (NDC (±0.5, ±0.5, z),
    unprojected), each across the map's ray through it (the cross product of the NDC x and y gradients there) and
    facing where the depth falls along it (rises, GREATER), projected. One answer, or several where the map's own
    triangles disagree (none of the golden maps')."""
    m = np.asarray(matrix, dtype=np.float64)
    answers = set()
    for x, y, z in ((x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.0, 0.5)):
        h = np.linalg.solve(m, [x, y, z, 1.0])
        p = h[:3] / h[3]
        clip = m @ np.append(p, 1.0)
        jac = (m[:3, :3] - np.outer(clip[:3] / clip[3], m[3, :3])) / clip[3]   # d NDC / d p
        ray = np.cross(jac[0], jac[1])
        towards = -ray * np.sign(jac[2] @ ray) * (-1.0 if depth_test == "GREATER" else 1.0)
        u = np.cross(towards, np.eye(3)[int(np.argmin(np.abs(towards)))])
        u, towards = u / np.linalg.norm(u), towards / np.linalg.norm(towards)
        width = 1e-6 * max(np.linalg.norm(p), 1e-300)
        corners = [m @ np.append(p + d * width, 1.0) for d in (np.zeros(3), u, np.cross(towards, u))]
        if min(c[3] for c in corners) <= 0.0:
            continue
        (ax, ay), (bx, by), (cx, cy) = (c[:2] / c[3] for c in corners)
        answers.add(bool((bx - ax) * (cy - ay) - (by - ay) * (cx - ax) < 0))
    return answers


@pytest.mark.parametrize("scale", [1.0, 1e-3, 1e3])
def test_every_golden_map_winds_as_its_own_triangles_at_any_scene_size(lx, scale):
    """The winding of a light-facing triangle that the depth pass culls by agrees with the map's own tiny triangles
    (``light_facing_winding_judged_at``) for every map of ``tests.warp.golden`` (714: every method on the examples,
    the hard cases and the bench scenes), and for the same scenes 1,000 times smaller and larger. It was read from a
    triangle across the central ray 1e-3 of the distance to the light (or, on a map with parallel rays, of
    |row 0 x row 1|) wide, which could reach w < 0 and project mirrored: 29 maps at their own size wound the other
    way (outdoor_sun's PSM and GLPR, bench spot's GMNPR and GLPR, ...), 197 at a thousandth of it."""
    import gzip
    import json
    with gzip.open(Path(__file__).parents[1] / "warp" / "golden.json.gz", "rt") as f:
        golden = json.load(f)
    wrong, judged = [], 0
    for name, setup in sorted(golden.items()):
        for m in setup.get("maps", []):
            matrix = np.reshape(m["matrix"], (4, 4)) @ np.diag([1.0 / scale] * 3 + [1.0])
            judged_as = light_facing_winding_judged_at(matrix, m["depth_test"])
            assert len(judged_as) == 1, f"{name} {m['role']}: its own triangles disagree"
            judged += 1
            if lx.pipeline.light_facing_winds_clockwise(lx.types.ShadowMap(matrix, (1024, 1024), m["depth_test"])) \
                    not in judged_as:
                wrong.append(f"{name} {m['role']}")
    assert judged == 714 and wrong == []


def edge_ramp_scene(scene, degrees=3.0):
    """A long box casting one straight shadow edge, rotated ``degrees`` against the
    map's texel grid, seen from straight above by an orthographic camera below
    the box (each map texel spans about four pixels)."""
    plane(scene, size=8)
    box(scene, size=(8, 4, 0.2), location=(0, 2.0, 1.0), rotation=(0, 0, math.radians(degrees)))
    camera(scene, (0, 0, 0.5), (0, 0, 0), res=(192, 192), ortho_scale=1.5)
    light(scene, "SUN", (0, 0, 10), energy=2.0)


RAMP_MAP = 48


def levels(out):
    s = out.shadow_mask[out.covered]
    return np.unique(np.round(s, 5))


@pytest.mark.parametrize("selection", ["MINMAX", "SORT"])
def test_mdsm_gives_more_shadow_levels_than_pcf(lx, scene, selection):
    edge_ramp_scene(scene)
    k = 3
    counts = {}
    for n in (1, 2, 3, 4):
        out, *_ = render(lx, scene, "uniform", RAMP_MAP,
                         shadow=dict(pcf_kernel=k, mdsm_depths=n, mdsm_selection=selection, mdsm_neighbourhood=3))
        lv = levels(out)
        counts[n] = len(lv)
        # every outcome is a multiple of 1 / (n k^2) (MDSM Table 1: at most n k^2 + 1 of them)
        np.testing.assert_allclose(lv * n * k * k, np.round(lv * n * k * k), atol=1e-3)
        assert len(lv) <= n * k * k + 1
    assert counts[1] <= k * k + 1
    assert counts[2] > counts[1] and counts[3] > counts[1] and counts[4] > counts[1], counts


def test_pcf_levels_follow_kernel_size(lx, scene):
    """An odd kernel weighs its k x k texels alike: k^2 + 1 shadow levels. An
    even kernel filters bilinearly: across an edge the shadow takes more
    levels than any box of k x k taps could."""
    edge_ramp_scene(scene)
    for k in (1, 3, 5):
        out, *_ = render(lx, scene, "uniform", RAMP_MAP, shadow=dict(pcf_kernel=k))
        lv = levels(out)
        assert len(lv) == k * k + 1, (k, lv)
    for k in (2, 4):
        out, *_ = render(lx, scene, "uniform", RAMP_MAP, shadow=dict(pcf_kernel=k))
        lv = levels(out)
        assert len(lv) > 2 * (k * k + 1) and lv.min() == 0.0 and lv.max() == 1.0, (k, lv)


@pytest.mark.parametrize("degrees", [12.0, 20.0])
def test_revectorized_pcf2_puts_a_straight_edge_on_its_line_not_on_the_texel_staircase(lx, scene, degrees):
    """A straight shadow edge at a shallow angle to the texel grid is stored as a
    staircase, runs of about 1 / tan(angle) texels; the bilinear PCF 2 follows
    the stairs (up to half a texel across the edge), revectorized it follows the
    line through the runs' ends: fewer than half as many pixels disagree with
    ray casting."""
    edge_ramp_scene(scene, degrees)
    wrong = {}
    for revectorize in (False, True):
        out, _, lt, _, dg = render(lx, scene, "uniform", RAMP_MAP, shadow=dict(pcf_kernel=2, revectorize=revectorize))
        ys, xs = np.nonzero(out.covered)
        truth = ray_shadow(bvh_of(dg), lt, out.world_position[ys, xs].astype(np.float64))
        assert 0.1 < truth.mean() < 0.9, "the edge must cross the view"
        wrong[revectorize] = int(((out.shadow_mask[ys, xs] > 0.5) != truth).sum())
    assert 0 < wrong[False] and wrong[True] <= 0.5 * wrong[False], wrong


def ideal_pcf2(shadow_map, points, bvh, above=0.05):
    """PCF 2 at world ``points`` on the ground (z = 0) recomputed from ``shadow_map``'s texels: each of the 2 x 2 taps
    a ray cast from its texel centre on the map's near plane, shadowed where it meets something ``above`` the ground
    first, weighed bilinearly as shade_frag.glsl weighs it."""
    m = np.asarray(shadow_map.matrix, dtype=np.float64)
    inv, size = np.linalg.inv(m), np.asarray(shadow_map.size)
    h = np.c_[points, np.ones(len(points))] @ m.T
    look = (h[:, :2] / h[:, 3:] * 0.5 + 0.5) * size - 0.5
    base, f = np.floor(look).astype(int), look - np.floor(look)
    out = np.zeros(len(points))
    for dx, dy in ((0, 0), (1, 0), (0, 1), (1, 1)):
        texel = np.clip(base + (dx, dy), 0, size - 1)
        ndc = (texel + 0.5) / size * 2.0 - 1.0
        near, far = (np.c_[ndc, np.full(len(ndc), z), np.ones(len(ndc))] @ inv.T for z in (-1.0, 1.0))
        near, far = near[:, :3] / near[:, 3:], far[:, :3] / far[:, 3:]
        hits = [bvh.ray_cast(Vector(a.tolist()), Vector((b - a).tolist()), float(np.linalg.norm(b - a)))[0]
                for a, b in zip(near, far)]
        shadowed = np.array([hit is not None and hit.z > above for hit in hits])
        out += (f[:, 0] if dx else 1.0 - f[:, 0]) * (f[:, 1] if dy else 1.0 - f[:, 1]) * shadowed
    return out


@pytest.mark.parametrize("turn, aspect", [(0.0, 1.0), (30.0, 1.0), (30.0, 2.0), (0.0, 0.5), (75.0, 2.0)])
def test_a_turned_or_2_to_1_map_renders_the_pcf2_its_texels_give(lx, scene, turn, aspect):
    """A map turned about the light's axis and laid out w:h = 2:1 (a cascade's) is drawn and read as a square one: at
    every ground pixel the rendered PCF 2 is the bilinear filter of its 2 x 2 texels, each ray-cast from its centre
    (a map read with its sides swapped, or texel centres half a texel off in x or y, misses this at the edge)."""
    edge_ramp_scene(scene, 20.0)
    dg = scene.view_layers[0].depsgraph
    dg.update()
    view, lt, bounds = lx.describe.describe_scene(scene, dg)
    plain = lx.warp.compute("uniform", view, lt, bounds, lx.warp.WarpOptions(shadow_map_size=(RAMP_MAP, RAMP_MAP)))
    c, s = math.cos(math.radians(turn)), math.sin(math.radians(turn))
    grow = abs(c) + abs(s)                         # the turned window holds the plain one, at the same texel density
    turned = np.eye(4)
    turned[:2, :2] = np.array([[c, s], [-s, c]]) / grow
    size = (round(RAMP_MAP * grow * math.sqrt(aspect)), round(RAMP_MAP * grow / math.sqrt(aspect)))
    setup = lx.types.ShadowSetup([replace(plain.maps[0], matrix=turned @ plain.maps[0].matrix, size=size)],
                                 plain.diagnostics)
    out, *_ = render(lx, scene, setup=setup, shadow=dict(pcf_kernel=2))
    ground = out.covered & (np.abs(out.world_position[..., 2]) < 1e-3)
    ys, xs = np.nonzero(ground)
    want = ideal_pcf2(setup.maps[0], out.world_position[ys, xs].astype(np.float64), bvh_of(dg))
    got = out.shadow_raw[ys, xs]
    assert np.sum((want > 0.0) & (want < 1.0)) > 500, "the edge must cross many texels"
    assert np.mean(np.abs(got - want) > 0.02) < 0.002 and np.mean(np.abs(got - want)) < 0.002


def test_multi_map_selection_matches_shadow_setup(lx, scene):
    """Three hand-made maps: a plane map with a region, a map limited to an eye-depth
    range, and a fallback. The shader picks the same map as ShadowSetup.map_index."""
    shadow_scene(scene, "SUN")
    dg = scene.view_layers[0].depsgraph
    dg.update()
    view, lt, bounds = lx.describe.describe_scene(scene, dg)
    T = lx.types
    g = lx.wgeom
    eye = -lt.direction * 20
    look = g.look_along(eye, lt.direction, (0, 0, 1) if abs(lt.direction[2]) < 0.9 else (0, 1, 0))

    def ortho(x0, x1, y0, y1):
        return g.ortho_matrix(x0, x1, y0, y1, 1.0, 40.0) @ look

    region = T.Region(normal=np.array([0.0, 0, 1]), offset=0.0,
                      polygon=np.array([[-4.0, -4, 0], [0, -4, 0], [0, 0, 0], [-4, 0, 0]]), tolerance=1e-3)
    maps = [
        T.ShadowMap(ortho(-8, 8, -8, 8), (1024, 1024), role="plane:0", region=region),
        T.ShadowMap(ortho(-8, 8, -8, 8), (768, 768), role="near", view_depth_range=(0.0, 8.5)),
        T.ShadowMap(ortho(-8, 8, -8, 8), (2048, 2048), role="fallback"),
    ]
    setup = T.ShadowSetup(maps, T.Diagnostics("hand-made"))
    out, view, light_, setup, dg = render(lx, scene, setup=setup)
    covered = out.covered
    pts = out.world_position[covered].astype(np.float64)
    expect = setup.map_index(pts, view)
    got = out.map_index[covered]
    assert set(np.unique(expect)) == {0, 1, 2}, "the scene must exercise every map"
    assert (got == expect).mean() > 0.995
    frac, n, _ = agreement(out, light_, dg)
    assert frac >= 0.99


def test_second_render_uploads_nothing(lx, scene):
    """A second frame of an unchanged scene reads no mesh, uploads nothing
    (batches, instance matrices, draw lists, render targets), keeps the
    culling index and culls nothing again; a moved object uploads its matrices
    but no mesh; an edited mesh uploads that mesh only."""
    shadow_scene(scene, "SUN")
    gc = lx.geometry.GeometryCache()
    gs = lx.batches.GPUScene()
    pool = lx.targets.TargetPool()

    def go():
        return cached_frame(lx, scene, gc, gs, "uniform", targets=pool)

    first, g1, b1 = go()
    assert first.counts.uploads == 2 and gc.extractions == 2
    assert first.counts.matrix_uploads == 1 and first.counts.target_allocations > 0
    culls = gs.culls
    assert culls == 4, "the receivers and the casters are culled, the solids the camera and the map see found"
    second, g2, b2 = go()
    assert gs.culls == culls, "an unchanged view and B culled again"
    c = second.counts
    assert (c.uploads, c.matrix_uploads, c.list_uploads, c.target_allocations) == (0, 0, 0, 0)
    assert gc.extractions == 2 and g2 is g1 and b2 is b1
    assert lx.culling.BoxIndex.of(b2, "casters") is lx.culling.BoxIndex.of(b1, "casters"), "index rebuilt"
    np.testing.assert_array_equal(first.shadow_mask, second.shadow_mask)
    named(scene, "Box").location.x += 0.5  # a transform: no geometry change
    third, g3, b3 = go()
    assert third.counts.uploads == 0 and third.counts.matrix_uploads == 1 and gc.extractions == 2
    assert b3 is not b1 and g3.meshes == g1.meshes and gs.culls == culls + 4
    me = named(scene, "Box").data
    me.vertices[0].co.z += 0.3
    me.update()
    fourth, *_ = go()
    assert fourth.counts.uploads == 1 and gc.extractions == 3


def test_two_scenes_drawn_in_turn_upload_each_once(lx):
    """F12's render depsgraph and the viewport's give two instance sets; drawn
    in turn, each keeps its matrices and draw lists on the GPU."""
    tri = (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float), np.array([[0, 1, 2]]))
    one = lx.geometry.SceneGeometry.from_arrays([("a", *tri, np.eye(4)[None])])
    two = lx.geometry.SceneGeometry.from_arrays([("a", *tri, np.stack([np.eye(4)] * 2))])
    gs = lx.batches.GPUScene()
    for _ in range(3):
        for g in (one, two):
            gs.sync(g)
            assert gs.instances is g.instances
            gs.draw_list("casters", np.ones(len(g.instances), dtype=bool))
    assert (gs.matrix_uploads, gs.list_uploads) == (2, 2)
    for n in range(gs.KEEP_SETS):          # older sets give way to newer ones
        gs.sync(lx.geometry.SceneGeometry.from_arrays([("a", *tri, np.stack([np.eye(4)] * (3 + n)))]))
    gs.sync(one)
    assert gs.matrix_uploads == 2 + gs.KEEP_SETS + 1


def test_moving_the_camera_or_the_light_rebuilds_no_index(lx, scene):
    """The camera and the light are not part of the scene's geometry: moving
    them re-culls (new draw lists) but reads no mesh, uploads no geometry or
    matrices and keeps the culling index."""
    lt = shadow_scene(scene, "SUN")
    gc = lx.geometry.GeometryCache()
    gs = lx.batches.GPUScene()

    def go():
        out, geometry, bounds = cached_frame(lx, scene, gc, gs, "lispsm")
        return out, geometry, lx.culling.BoxIndex.of(bounds, "casters")

    _, g0, index = go()
    for move in (lambda: setattr(scene.camera, "location", scene.camera.location + Vector((1.5, 0.5, 0.2))),
                 lambda: setattr(lt, "rotation_euler", (math.radians(20), 0.1, math.radians(60)))):
        move()
        out, g, again = go()
        c = out.counts
        assert g is g0 and again is index, "the scene's geometry or culling index was rebuilt"
        assert (c.uploads, c.matrix_uploads) == (0, 0) and gc.extractions == 2


def test_caster_culling_counts(lx, scene):
    shadow_scene(scene, "SUN")
    far = box(scene, "FarAway", location=(60, 60, 1))
    hidden = box(scene, "NoShadow", location=(-1.5, 1.5, 0.5))
    hidden.visible_shadow = False
    ghost = box(scene, "Ghost", location=(-1.5, -1.5, 0.5))  # casts, but the camera does not see it
    ghost.visible_camera = False
    out, view, lt, setup, dg = render(lx, scene, "uniform", 512)
    c = out.counts
    assert c.casters_drawn == 3
    assert c.casters_culled == 1 and c.caster_triangles_culled == 12
    assert c.non_casters == 1
    assert c.receivers_drawn == 3  # ground, box, NoShadow (FarAway is outside the view)
    on_ghost = out.covered & (np.abs(out.world_position[..., 0] + 1.5) < 0.45) & \
        (np.abs(out.world_position[..., 1] + 1.5) < 0.45) & (out.world_position[..., 2] > 0.05)
    assert not on_ghost.any(), "an object hidden from the camera must not be drawn"


def nearest_surface_errors(out, view, dg):
    """Covered pixels whose camera ray meets geometry before the surface the frame saw there (ray-cast)."""
    bvh = bvh_of(dg)
    eye = Vector(view.position.tolist())
    bad = 0
    for p in out.world_position[out.covered][::7]:
        d = Vector(p.tolist()) - eye
        hit = bvh.ray_cast(eye, d.normalized(), d.length * 1.01)
        bad += hit[0] is None or hit[3] < d.length * (1.0 - 1e-3)
    return bad


@pytest.mark.parametrize("where", ["outside", "inside a room"])
def test_the_prepass_culls_back_faces_only_where_front_faces_hide_them(lx, scene, where):
    """The camera pre-pass culls the back faces of solids seen from outside (a
    closed box, a mirrored one), not those of an open plane, an inside-out box
    or a room the camera stands in; every pixel still sees the nearest surface."""
    plane(scene, size=30.0)
    box(scene, "Solid", location=(-1.5, 0.0, 1.0))
    box(scene, "Mirrored", location=(1.5, 0.0, 1.0)).scale = (-1.0, 1.0, 1.0)
    inside_out = box(scene, "InsideOut", location=(0.0, 2.5, 1.0))
    faces = [tuple(reversed(p.vertices)) for p in inside_out.data.polygons]
    mesh_object(scene, "InsideOutMesh", [v.co for v in inside_out.data.vertices], faces, (0.0, 2.5, 1.0))
    bpy.data.objects.remove(inside_out)
    cam = camera(scene, (0.0, -8.0, 5.0), (0, 0, 0))
    aim(cam, (0.0, 0.0, 1.0))
    light(scene, "SUN", energy=3.0).rotation_euler = (math.radians(30), 0, math.radians(20))
    if where != "outside":
        box(scene, "Room", size=(40.0, 40.0, 40.0), location=(0.0, 0.0, 0.0))
    dg = scene.view_layers[0].depsgraph
    dg.update()
    geometry = lx.geometry.GeometryCache().update(dg)
    view, *_ = lx.describe.describe_scene(scene, dg, instances=geometry.instances)
    frame = lx.pipeline.ShadowFrame(geometry, view, scene=lx.batches.GPUScene())
    frame.camera_prepass()
    assert (frame.solids.instance_count, frame.receivers.instance_count) == ((2, 2) if where == "outside" else (2, 3))
    out, view, _, _, dg = render(lx, scene, "uniform", 512)
    assert out.covered.mean() > (0.3 if where == "outside" else 0.999)
    assert nearest_surface_errors(out, view, dg) == 0


def test_each_map_culls_faces_turned_from_the_light_only_on_solids_it_sees_from_outside(lx, lixel, scene):
    """The depth pass culls the faces turned from the light of the solids a map
    sees from outside: the maps are those of drawing every face; a room the
    point light stands in is drawn whole in every map."""
    box(scene, "Solid", size=(1.0, 1.0, 2.0), location=(0.8, 0.5, 1.0), rotation=(0.0, 0.0, 0.3))
    box(scene, "Room", size=(12.0, 12.0, 8.0), location=(0.0, 0.0, 3.99))
    lt = light(scene, "POINT", (0.0, 0.0, 4.5), energy=500.0)
    cam = camera(scene, (0.0, -5.0, 3.0), (0, 0, 0))
    aim(cam, (0.0, 0.0, 0.5))
    frame, setup, shadow = drawn_frame(lx, lixel, scene, "uniform", 1024)
    solids = [{g.key[1] for g in s.groups} for s in frame.map_solids]
    assert len(setup.maps) > 1 and all("Room" not in s for s in solids) and any("Solid" in s for s in solids)
    whole = lx.pipeline.depth_pass(setup, frame.scene, frame.casters, shadow, lx.targets.TargetPool())
    for (_, culled_fb), (_, whole_fb), m in zip(frame.maps, whole, setup.maps):
        a, b = lx.compose.read_depth(culled_fb, m.size), lx.compose.read_depth(whole_fb, m.size)
        assert np.mean(np.abs(a - b) > 1e-5) < 1e-4, "a map differs from drawing every face"
    bare_culled, bare = (lx.pipeline.depth_pass(setup, frame.scene, casters, shadow, lx.targets.TargetPool(), bare=True,
                                                solids=solids)
                         for casters, solids in ((frame.map_casters, frame.map_solids), (frame.casters, None)))
    for (_, culled_fb), (_, whole_fb), m in zip(bare_culled, bare, setup.maps):
        a, b = lx.compose.read_depth(culled_fb, m.size), lx.compose.read_depth(whole_fb, m.size)
        assert np.mean(np.abs(a - b) > 1e-5) < 1e-4, "the benchmarks' bare draw culling the same faces differs"


def drawn_frame(lx, lixel, scene, method, size):
    """(the scene's ShadowFrame with ``method``'s maps of ``size``² drawn as the engine draws them, its setup, the
    default ShadowSettings)."""
    dg = scene.view_layers[0].depsgraph
    dg.update()
    geometry = lx.geometry.GeometryCache().update(dg)
    view, lt, bounds = lx.describe.describe_scene(scene, dg, instances=geometry.instances)
    frame = lx.pipeline.ShadowFrame(geometry, view, scene=lx.batches.GPUScene())
    frame.camera_prepass()
    body, setup, _ = importlib.import_module(f"{lixel.__name__}.addon.render.engine").fit_warp(
        frame, lt, bounds, lx.warp.WarpOptions(shadow_map_size=(size, size)), method)
    shadow = lx.settings.ShadowSettings()
    frame.draw_maps(setup, shadow, body)
    return frame, setup, shadow


def culled_and_whole_maps(lx, lixel, scene, method, size=512):
    """(each map as the frame draws it, culling the faces turned from the light of the solids it sees from outside;
    the same map drawing every face), window depths, and the maps' roles."""
    frame, setup, shadow = drawn_frame(lx, lixel, scene, method, size)
    assert frame.casters.instance_count == 2
    whole = lx.pipeline.depth_pass(setup, frame.scene, frame.casters, shadow, lx.targets.TargetPool())
    return [(lx.compose.read_depth(c, m.size), lx.compose.read_depth(w, m.size), m.role)
            for (_, c), (_, w), m in zip(frame.maps, whole, setup.maps)]


@pytest.mark.parametrize("scale", [1.0, 0.01])
@pytest.mark.parametrize("kind", ["SUN", "SPOT", "POINT"])
@pytest.mark.parametrize("method", METHOD_NAMES)
def test_culling_keeps_the_faces_towards_the_light_for_every_method_at_any_scene_size(lx, lixel, scene, method, kind,
                                                                                      scale):
    """The depth pass culls a solid's faces turned from the light (``light_facing_winds_clockwise``), so each map
    holds what drawing every face gives. The winding was read from a triangle across the map's central ray that could
    reach w < 0, where it projects mirrored: then the faces towards the light were culled and the back faces drawn,
    which lost the box's shadow on its own dark side (the Shadow pass) -- for LiSPSM's and the cascade's sun maps in
    this scene made 1 cm wide (and in 29 of the 714 maps of ``tests.warp.golden`` at their own size: outdoor_sun's
    PSM and GLPR, bench spot's GMNPR, ...)."""
    build(scene, light=kind)
    for ob in scene.objects:
        ob.location *= scale
        ob.scale *= scale
    scene.camera.data.clip_start *= scale
    scene.camera.data.clip_end *= scale
    for culled, whole, role in culled_and_whole_maps(lx, lixel, scene, method):
        assert np.mean(np.abs(culled - whole) > 1e-5) < 1e-4, f"{role}: culling drew other faces than the whole map"


def test_a_mesh_bounds_solids_when_closed_with_normals_outwards(lx):
    corners = np.array([(x, y, z) for z in (0, 1) for y in (0, 1) for x in (0, 1)], dtype=np.float32)
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    cube = np.array([t for q in quads for t in ((q[0], q[1], q[2]), (q[0], q[2], q[3]))], dtype=np.int32)
    two = np.concatenate([corners, corners + 3.0])

    def solid(positions, triangles):
        return lx.geometry.MeshData(("test",), positions, np.ascontiguousarray(triangles)).bounds_solids
    assert solid(corners, cube)
    assert solid(two, np.concatenate([cube, cube + 8])), "two cubes, each closed and outwards"
    assert not solid(corners, cube[:, ::-1]), "inside out"
    assert not solid(corners, cube[:-1]), "a hole"
    assert not solid(two, np.concatenate([cube, cube[:, ::-1] + 8])), "one part inside out"
    assert not solid(corners, np.concatenate([cube, cube[:2]])), "a face twice"


def test_a_mesh_whose_vertices_moved_keeps_its_closed_parts_and_finds_its_volumes_again(lx, scene):
    """A viewport edit that moves vertices only re-reads the mesh with the
    same triangles: the new content takes the closed surface's parts from the
    old, and the volumes are found again (a mirror turns it inside out). While
    it is being edited the mesh is drawn whole (no solid: right whatever the
    edit did); the test runs once an update finds it unchanged (the edits stopped)."""
    ob = box(scene, "Solid", size=(1.0, 2.0, 3.0))
    dg = scene.view_layers[0].depsgraph
    dg.update()
    cache = lx.geometry.GeometryCache()
    first = next(iter(cache.update(dg).meshes.values()))
    assert first.bounds_solids, "a mesh read for the first time is tested at once"

    def edited_then_settled():
        ob.data.update()
        dg.update()
        edited = next(iter(cache.update(dg).meshes.values()))
        assert not edited.settled and not edited.bounds_solids and "encloses_solids" not in edited.__dict__, \
            "tested while being edited"
        assert next(iter(cache.update(dg).meshes.values())) is edited and edited.settled
        return edited

    ob.data.vertices[0].co.z += 0.1
    moved = edited_then_settled()
    assert moved.bounds_solids, "still a solid once settled"
    for v in ob.data.vertices:
        v.co.x = -v.co.x
    mirrored = edited_then_settled()
    assert mirrored is not first and np.array_equal(mirrored.triangles, first.triangles)
    assert mirrored.closed_parts is first.closed_parts, "the parts are not found again"
    assert not mirrored.bounds_solids, "inside out after the vertices moved"
    ob.data.polygons[0].flip()
    flipped = edited_then_settled()
    assert flipped.closed_parts is None and not flipped.bounds_solids, "new triangles: tested again, one face flipped"
    at_once = lx.geometry.GeometryCache(defer_solids=False)
    at_once.update(dg)
    ob.data.polygons[0].flip()
    for v in ob.data.vertices:
        v.co.x = -v.co.x
    ob.data.update()
    dg.update()
    assert next(iter(at_once.update(dg).meshes.values())).bounds_solids, "tested at once without deferring"


def test_too_many_maps_is_a_clear_error(lx, scene):
    shadow_scene(scene, "SUN")
    dg = scene.view_layers[0].depsgraph
    dg.update()
    view, lt, bounds = lx.describe.describe_scene(scene, dg)
    setup = lx.warp.compute("uniform", view, lt, bounds, lx.warp.WarpOptions(shadow_map_size=(64, 64)))
    setup.maps = setup.maps * 9
    with pytest.raises(lx.types.WarpError, match="at most 8"):
        lx.pipeline.render_shadows(view, lt, setup, lx.geometry.GeometryCache().update(dg))


def test_eye_space_blur_is_strongest_near_the_viewer(lx):
    """Scherzer §4.3: near shadows are blurred most, distant detail is kept
    (the GPU pass on a made-up shading result)."""
    import gpu
    h, w = 40, 80
    data = np.zeros((h, w, 4), np.float32)
    data[:, 40:, 0] = 1.0                                                   # one vertical shadow edge
    data[..., 3] = np.repeat(np.linspace(1.0, 10.0, h)[:, None], w, 1)      # eye depth, row 0 nearest
    tex = gpu.types.GPUTexture((w, h), format="RGBA32F", data=gpu.types.Buffer("FLOAT", data.size, data.ravel()))
    pool = lx.targets.TargetPool()
    d_near, d_far = lx.compose.reduce_range(pool, tex, (w, h), channel=3, above=0.0)
    assert (d_near, d_far) == (1.0, 10.0)
    mask = lx.compose.eye_blur_pass(pool, (w, h), tex, 6.0, d_near)
    out = lx.compose.read_color(pool.framebuffer(colors=(mask,)), 0, (w, h), 1)
    width = lambda row: int(((out[row] > 0.01) & (out[row] < 0.99)).sum())  # noqa: E731
    assert width(0) >= 10 and width(h - 1) <= 2 and width(0) > width(h // 2) >= width(h - 1)
    np.testing.assert_array_equal(out[:, :34], 0.0)
    np.testing.assert_array_equal(out[:, 46:], 1.0)


def test_eye_blur_setting_reaches_the_render(lx, scene):
    shadow_scene(scene, "SUN")
    sharp, *_ = render(lx, scene, "uniform", 512, shadow=dict(pcf_kernel=1))
    soft, *_ = render(lx, scene, "uniform", 512, shadow=dict(pcf_kernel=1, eye_blur=4.0))
    partial = lambda o: int(((o.shadow_mask > 0.01) & (o.shadow_mask < 0.99)).sum())  # noqa: E731
    assert partial(sharp) == 0 and partial(soft) > 100
    np.testing.assert_array_equal(soft.shadow_raw, sharp.shadow_raw)


@pytest.mark.parametrize("selection", ["MINMAX", "SORT"])
def test_mdsm_on_every_map_of_a_multi_map_setup(lx, scene, selection):
    """A point light whose maps are several frusta (or cube faces): MDSM keys are
    built per map and the n-shadow test agrees with ray casting away from edges."""
    shadow_scene(scene, "POINT")
    opts = lx.warp.WarpOptions(shadow_map_size=(1024, 1024), max_frustum_angle=math.radians(60))
    out, view, lt, setup, dg = render(lx, scene, "uniform", warp_options=opts,
                                      shadow=dict(mdsm_depths=3, mdsm_selection=selection, pcf_kernel=3))
    assert len(setup.maps) > 1
    assert len(out.mdsm_keys) == len(setup.maps)
    assert len(np.unique(out.map_index[out.covered])) > 1
    frac, n, _ = agreement(out, lt, dg)
    assert frac >= 0.99


def test_far_from_the_origin_shadows_keep_their_precision(lx, scene):
    """The whole scene moved 1000 km away (float32 spacing there: 6 cm): the GPU
    works relative to the scene's drawing origin, so the shadows still agree with ray casting."""
    shadow_scene(scene, "SUN")
    for ob in scene.objects:
        ob.location.x += 1.0e6
        ob.location.y -= 1.0e6
    out, view, lt, setup, dg = render(lx, scene, "uniform", 2048)
    frac, n, truth = agreement(out, lt, dg)
    assert n > 5000 and truth[out.covered].mean() > 0.02
    assert frac >= 0.99


def test_the_map_picture_on_the_gpu_is_depth_to_rgba(lx, scene, lixel):
    """The viewport's shadow-map picture (compose.map_picture, no read-back) is
    the picture renders.depth_to_rgba makes of the read-back map's every step-th texel."""
    renders = importlib.import_module(f"{lixel.__name__}.addon.ui.renders")
    shadow_scene(scene, "SUN")
    dg = scene.view_layers[0].depsgraph
    dg.update()
    geometry = lx.geometry.GeometryCache().update(dg)
    view, lt, bounds = lx.describe.describe_scene(scene, dg, instances=geometry.instances)
    setup = lx.warp.compute("lispsm", view, lt, bounds, lx.warp.WarpOptions(shadow_map_size=(300, 200)))
    pool = lx.targets.TargetPool()
    frame = lx.pipeline.ShadowFrame(geometry, view, read={"combined"}, scene=lx.batches.GPUScene(), targets=pool)
    frame.camera_prepass()
    frame.draw_maps(setup, lx.settings.ShadowSettings(), lx.warp.intersection_body(view, lt, bounds))
    depth = lx.compose.read_depth(frame.maps[0][1], (300, 200))
    assert 0.1 < (depth < 1.0).mean() < 1.0 and np.ptp(depth[depth < 1.0]) > 0.01   # a map to picture
    for longest in (64, 300, 1000):
        tex = lx.compose.map_picture(pool, "picture", frame.maps[0][0], (300, 200), longest)
        got = lx.compose.read_color(pool.framebuffer(colors=(tex,)), 0, (tex.width, tex.height))
        step = max(1, -(-300 // longest))
        np.testing.assert_allclose(got, renders.depth_to_rgba(depth[::step, ::step]), atol=2e-6)


def edge_on_scene(scene, X=30.0):
    """A 20 m long wall (2 m thick, 4 m high) on the ground, its x- face at x = X - 1, which a camera 25 m away sees
    nearly edge-on (0.5 m in front of its plane: 0.4-2.8 px wide at 320²) and a point light 30 m away lights at
    n·l ≈ 0.006 (0.2 m in front of it), X m from the drawing origin (the ground's centre), as in
    gen64_04_point_behind_camera."""
    plane(scene, size=4 * X)
    box(scene, size=(2.0, 20.0, 4.0), location=(X, 0.0, 2.0))
    ob = camera(scene, (X - 1.5, -25.0, 2.0), (0, 0, 0), res=(320, 320))
    aim(ob, (X - 0.8, 0.0, 1.6))
    light(scene, "POINT", (X - 1.2, 30.0, 3.0), energy=2.0e5)


def test_a_face_seen_edge_on_is_where_the_pre_pass_puts_it_and_unshadowed_at_4096(lx, scene):
    """The pre-pass's position of each pixel of a face seen edge-on lies on that face within a few float32 steps of
    its distance from the drawing origin, and a grazing light shows no acne on it at 4096². Interpolated in world
    coordinates it lay up to 0.06 mm off this face (0.18 mm on gen64_04's, whose light's n·l of 0.0064 stretched
    that past the bias at 4096²: a column of false shadow that 2048² did not have); interpolated in the camera's
    clip coordinates its float32 rounding moves it along the eye ray, within the face (camera_lib.glsl)."""
    X = 30.0
    edge_on_scene(scene, X)
    out, *_ = render(lx, scene, "uniform", 4096)
    face = out.covered & (np.abs(out.world_normal[..., 0] + 1.0) < 1e-3)
    assert face.sum() > 300
    off = np.abs(out.world_position[face][:, 0] - (X - 1.0))
    assert off.max() < 8 * X * 2.0 ** -24, f"P lies {off.max() * 1e3:.4f} mm off the face"
    assert (out.shadow_mask[face] > 0).sum() == 0
