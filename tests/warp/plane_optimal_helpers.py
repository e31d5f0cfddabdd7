"""Shared helpers for the plane_optimal tests: scenes, cameras and an
independent measurement of the screen-pixel -> texel map on a plane.

The measurement uses only the View, the ShadowMap's matrix and size and the
plane: pixel (px, py) -> the world point of the plane under that pixel -> the
map's texel coordinates ((ndc + 1)/2 * size). Both steps are projective, so
the composite is a 3x3 homography G whose Jacobian is exact in float64.
"""
from __future__ import annotations

import math

import numpy as np

from addon.warp import EmptyBodyError, Light, SceneBounds, View, WarpOptions, compute, intersection_body
from addon.warp.geometry import look_along
from addon.warp.plane_map import FLAT_RATIO, PlaneOfInterest, line_plane_points

FLOOR = np.array([[-50.0, -50.0, -0.1], [50.0, 50.0, 0.0]])
BLOCKS = np.array([
    [[-1.0, 3.0, 0.0], [1.0, 5.0, 2.0]],
    [[4.0, 8.0, 0.0], [5.0, 9.0, 4.0]],
    [[-6.0, 12.0, 0.0], [-4.0, 14.0, 1.0]],
    [[2.0, -3.0, 0.0], [3.0, -2.0, 3.0]],
])
FLOOR_PLANE = ((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))


def scene(extra=()) -> SceneBounds:
    boxes = [FLOOR, *BLOCKS, *extra]
    return SceneBounds.from_boxes(np.array(boxes))


def camera(position, target, fov_deg=60.0, resolution=(640, 360), near=0.1, far=80.0, up=(0.0, 0.0, 1.0)) -> View:
    pos = np.asarray(position, dtype=np.float64)
    fwd = np.asarray(target, dtype=np.float64) - pos
    c2w = np.linalg.inv(look_along(pos, fwd, up))
    return View.perspective(c2w, math.radians(fov_deg), resolution[0] / resolution[1], near, far, resolution)


def camera_yaw_pitch(position, yaw_deg, pitch_deg, **kw) -> View:
    yaw, pitch = math.radians(yaw_deg), math.radians(pitch_deg)
    fwd = np.array([math.cos(pitch) * math.sin(yaw), math.cos(pitch) * math.cos(yaw), math.sin(pitch)])
    return camera(position, np.asarray(position, dtype=np.float64) + fwd, **kw)


def sun(direction) -> Light:
    return Light("SUN", direction=np.asarray(direction, dtype=np.float64))


def sun_at(elevation_deg, azimuth_deg) -> Light:
    """A sun whose light arrives from ``elevation`` above the horizon."""
    e, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    towards = np.array([math.cos(e) * math.sin(a), math.cos(e) * math.cos(a), math.sin(e)])
    return sun(-towards)


def point(position) -> Light:
    return Light("POINT", position=np.asarray(position, dtype=np.float64))


def run(view, light, sc=None, **opts):
    sc = scene() if sc is None else sc
    options = WarpOptions(**{"shadow_map_size": (2048, 2048), "planes": (FLOOR_PLANE,), **opts})
    body = intersection_body(view, light, sc)
    setup = compute("plane_optimal", view, light, sc, options, body=body)
    setup.inputs = (light, sc)   # test bookkeeping: what the setup was computed for
    return setup, body


def try_run(view, light, sc=None, **opts):
    """``run`` or (None, None) when nothing visible can be shadowed (B empty)."""
    try:
        return run(view, light, sc, **opts)
    except EmptyBodyError:
        return None, None


def plane_maps(setup):
    return [(i, m) for i, m in enumerate(setup.maps) if m.role.startswith("plane:")]


def plane_scale(setup):
    """The plane maps' lixels per pixel (along each axis)."""
    return setup.diagnostics.extra["budget"]["lixels_per_pixel"]


def assert_pixel_centres_are_lixel_centres(view, setup):
    """Chong-Gortler §2, "for each pixel ... exactly one lixel ... samples the
    exact same geometric point": one lixel per pixel, and on the plane pixel
    -> texel is t = p + c (no scale, rotation or perspective) with c a whole
    number, so the centre p = i + ½ of every pixel i is the centre of texel i + c."""
    assert plane_scale(setup) == 1.0
    for _, m in plane_maps(setup):
        g = pixel_to_texel_homography(view, m, m.region.normal, m.region.normal * m.region.offset)
        g = g / g[2, 2]
        assert np.allclose(g[:2, :2], np.eye(2), atol=1e-9) and np.allclose(g[2, :2], 0, atol=1e-12)
        assert np.allclose(g[:2, 2], np.round(g[:2, 2]), atol=1e-6)


def plane_basis(normal, point):
    n = np.asarray(normal, dtype=np.float64)
    n = n / np.linalg.norm(n)
    e1 = np.cross(n, np.eye(3)[int(np.argmin(np.abs(n)))])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    return np.column_stack([np.append(e1, 0), np.append(e2, 0), np.append(point, 1.0)])  # 4x3


def raster(size):
    w, h = size
    return np.array([[w / 2, 0, w / 2], [0, h / 2, h / 2], [0, 0, 1.0]])


def pixel_to_texel_homography(view: View, shadow_map, normal, point) -> np.ndarray:
    """G (3x3) with texel_h = G @ (px, py, 1) for points of the plane (normal, point)."""
    b = plane_basis(normal, point)
    hv = raster(view.resolution) @ view.world_to_clip[[0, 1, 3]] @ b
    hl = raster(shadow_map.size) @ shadow_map.matrix[[0, 1, 3]] @ b
    return hl @ np.linalg.inv(hv)


def homography_jacobian(g: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """(N, 2, 2) d texel / d pixel of the homography g at (N, 2) pixels."""
    p = np.column_stack([pixels, np.ones(len(pixels))])
    h = p @ g.T
    w = h[:, 2]
    t = h[:, :2] / w[:, None]
    j = (g[None, :2, :2] - t[:, :, None] * g[None, 2:3, :2]) / w[:, None, None]
    return j


def region_pixels(view: View, shadow_map, count=400, seed=0) -> tuple[np.ndarray, np.ndarray]:
    """Random world points of the map's region polygon (on its plane) and their pixels."""
    rng = np.random.default_rng(seed)
    poly = shadow_map.region.polygon
    wts = rng.dirichlet(np.ones(len(poly)), size=count)
    pts = np.concatenate([wts @ poly, poly])
    clip = np.column_stack([pts, np.ones(len(pts))]) @ view.world_to_clip.T
    ndc = clip[:, :2] / clip[:, 3:4]
    px = (ndc + 1) / 2 * np.array(view.resolution)
    return pts, px


def ndc(matrix, points) -> tuple[np.ndarray, np.ndarray]:
    h = np.column_stack([points, np.ones(len(points))]) @ np.asarray(matrix).T
    return h[:, :3] / h[:, 3:4], h[:, 3]


def body_samples(body, count=800, seed=1) -> np.ndarray:
    """Points spread through B (its vertices and random convex combinations)."""
    rng = np.random.default_rng(seed)
    v = body.vertices
    wts = rng.dirichlet(np.full(len(v), 0.3), size=count)
    return np.concatenate([v, wts @ v])


def check_coverage(view, light, sc, setup, body, samples=(160, 90)):
    """The coverage rule, measured independently (``addon.measure.box_scene``):
    every visible point of the box scene (ray-cast from a pixel grid) is served
    by a map (w > 0, NDC in [-1, 1]), every caster box crossing its shadow ray
    lies in that same map with a nearer depth, and every point of B on the
    shadow ray of a visible point lies in the serving map's clip volume: the
    plane maps hold what shadows their region, the fallback the rest of B."""
    from addon.measure.box_scene import judge, visible_points
    verdict = judge(view, light, sc, setup, samples)
    assert verdict.visible > 0
    assert verdict.uncovered == 0, f"{verdict.uncovered} of {verdict.visible} visible points unserved"
    assert verdict.casters_uncovered == 0, f"{verdict.casters_uncovered} casters outside their receiver's map"
    assert verdict.depth_order_wrong == 0
    pts, _ = visible_points(view, sc, samples)
    if light.type == "SPOT":
        lit = light.rays_to(pts) @ light.direction >= math.cos(light.spot_angle / 2)
        pts = pts[lit]
    idx = setup.map_index(pts, view)
    rng = np.random.default_rng(7)
    t = rng.uniform(0, 1, size=len(pts))
    if light.is_directional:
        reach = np.abs(body.vertices - view.position).max() * 4
        ray_pts = pts - (t * reach)[:, None] * light.direction
    else:
        ray_pts = light.position + t[:, None] * (pts - light.position)
    ok = body.contains(ray_pts, tol=0.0)
    for i, m in enumerate(setup.maps):
        sel = ok & (idx == i)
        if sel.any():
            assert np.all(m.contains(ray_pts[sel], 1e-9)), f"{m.role}: points of B on shadow rays outside the map"
    return verdict


def ray_plane_points(view_clip, plane_vec, ndc_xy) -> np.ndarray:
    """Homogeneous (N, 4) points where the viewer rays through NDC ``ndc_xy``
    (N, 2) meet the plane π (``line_plane_points`` of each ray's near and far
    points): also where they meet P behind the camera or at infinity (w <= 0)."""
    inv = np.linalg.inv(np.asarray(view_clip, dtype=np.float64))
    xy = np.asarray(ndc_xy, dtype=np.float64).reshape(-1, 2)
    k = len(xy)
    ends = np.ones((2 * k, 4))                      # the near points (z = -1), then the far ones (z = 1)
    ends[:k, :2] = ends[k:, :2] = xy
    ends[:k, 2] = -1.0
    ends = ends @ inv.T
    return line_plane_points(ends[:k], ends[k:], plane_vec)


def default_plane(receiver_boxes):
    """The reference for ``plane_map.default_plane`` without a seen surface: the top
    face of the widest flat box (height <= FLAT_RATIO x its smaller side), then
    the thinnest, then the first; None when no box is flat."""
    b = np.asarray(receiver_boxes, dtype=np.float64).reshape(-1, 2, 3)
    ext = b[:, 1] - b[:, 0]
    side = np.minimum(ext[:, 0], ext[:, 1])
    area = np.where((side > 0) & (ext[:, 2] <= FLAT_RATIO * side), ext[:, 0] * ext[:, 1], -1.0)
    if not len(b) or area.max() < 0:
        return None
    widest = np.flatnonzero(area == area.max())
    i = int(widest[np.argmin(ext[widest, 2])])
    (x0, y0, _), (x1, y1, top) = b[i]
    face = np.array([[x0, y0, top], [x1, y0, top], [x1, y1, top], [x0, y1, top]])
    return PlaneOfInterest(np.array([0.0, 0.0, 1.0]), float(top), face, f"top of receiver box {i}")
