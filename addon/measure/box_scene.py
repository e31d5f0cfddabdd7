"""An independent judge of light matrices on box scenes (numpy only).

It trusts nothing the warp core computed on the way (no B, no frames, no
visible region; only the slab test of ``addon.warp.rays`` is shared, :func:`ray_boxes`): it casts
rays through a grid of camera pixels against the scene's boxes to find the
visible points, walks each point's shadow ray toward the light through the
caster boxes, and checks what an outside evaluation checks:

* coverage - every visible point is served by a map (``ShadowSetup.map_index``)
  with w > 0 and NDC x, y, z in [-1, 1], and every caster point on its shadow
  ray lies in that *same* map (else the map cannot shadow it) with a depth that
  wins the map's depth test against the receiver;
* texel footprint - screen pixels per texel at each visible point
  (``footprint.setup_texel_footprint``), summarised at p95 and max.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .footprint import setup_texel_footprint
from ..warp.geometry import transform_points
from ..warp.rays import first_hits, slab_intervals
from ..warp.types import Light, SceneBounds, ShadowSetup, View


def ray_boxes(origins, directions, t_max, boxes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest hit of each ray with (M, 2, 3) boxes within [0, t_max]: (t, box, hit
    face normal), t = inf where nothing is hit; every ray against every box."""
    origins = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    directions = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 2, 3)
    rows = np.arange(len(origins))
    with np.errstate(divide="ignore"):
        inverse = 1.0 / directions
    enter, leave, axes = slab_intervals(origins[:, None, :], inverse[:, None, :],
                                        boxes[None, :, 0, :], boxes[None, :, 1, :], hit_axis=True)
    t = first_hits(enter, leave, np.asarray(t_max, dtype=np.float64)[:, None])
    if t.shape[1] == 0:
        return np.full(len(origins), np.inf), np.zeros(len(origins), dtype=np.int64), np.zeros_like(origins)
    box = np.argmin(t, axis=1)
    tt = t[rows, box]
    axis = axes[rows, box]
    normal = np.zeros_like(origins)
    normal[rows, axis] = -np.sign(directions[rows, axis])
    return tt, box, normal


def pixel_rays(view: View, samples: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Origins, unit directions and [t_near, t_far] of rays through pixel centres
    of a ``samples`` = (nx, ny) grid over the image."""
    nx, ny = samples
    x = (np.arange(nx) + 0.5) / nx * 2 - 1
    y = (np.arange(ny) + 0.5) / ny * 2 - 1
    gx, gy = np.meshgrid(x, y)
    inv = np.linalg.inv(view.world_to_clip)
    near = transform_points(inv, np.stack([gx.ravel(), gy.ravel(), -np.ones(gx.size)], axis=1))
    far = transform_points(inv, np.stack([gx.ravel(), gy.ravel(), np.ones(gx.size)], axis=1))
    d = far - near
    length = np.linalg.norm(d, axis=1)
    return near, d / length[:, None], length


def visible_points(view: View, scene: SceneBounds, samples=(96, 54)) -> tuple[np.ndarray, np.ndarray]:
    """Visible receiver points and their normals on a pixel grid."""
    o, d, length = pixel_rays(view, samples)
    t, _, n = ray_boxes(o, d, length, scene.receivers)
    hit = np.isfinite(t)
    return o[hit] + t[hit, None] * d[hit], n[hit]


def caster_points(points, light: Light, scene: SceneBounds) -> tuple[np.ndarray, np.ndarray]:
    """Points where shadow rays from ``points`` toward the light cross the
    surface of a caster box (boxes are closed shells), with the receiver index."""
    if len(scene.casters) == 0 or len(points) == 0:
        return np.zeros((0, 3)), np.zeros(0, dtype=int)
    if light.is_directional:
        d = np.broadcast_to(-light.direction, points.shape)
        t_max = np.full(len(points), np.inf)
    else:
        to_light = light.position - points
        t_max = np.linalg.norm(to_light, axis=1)
        d = to_light / t_max[:, None]
    extent = np.linalg.norm(scene.aabb()[1] - scene.aabb()[0])
    eps = 1e-6 * extent
    o = points + eps * d
    boxes = scene.casters
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d[:, None, :]
        t1 = (boxes[None, :, 0, :] - o[:, None, :]) * inv
        t2 = (boxes[None, :, 1, :] - o[:, None, :]) * inv
    t1 = np.where(np.isnan(t1), -np.inf, t1)
    t2 = np.where(np.isnan(t2), np.inf, t2)
    enter = np.minimum(t1, t2).max(axis=2)
    leave = np.maximum(t1, t2).min(axis=2)
    crosses = enter <= leave
    pts, owner = [], []
    for t in (enter, leave):
        r, b = np.nonzero(crosses & (t > 0) & (t < t_max[:, None] * (1 - 1e-9)))
        pts.append(o[r] + t[r, b][:, None] * d[r])
        owner.append(r)
    return np.concatenate(pts), np.concatenate(owner)


@dataclass
class Judgement:
    visible: int
    uncovered: int
    casters: int
    casters_uncovered: int
    depth_order_wrong: int
    footprint_p95: float
    footprint_max: float

    @property
    def covering(self) -> bool:
        return self.uncovered == 0 and self.casters_uncovered == 0 and self.depth_order_wrong == 0


def judge(view: View, light: Light, scene: SceneBounds, setup: ShadowSetup, samples=(96, 54),
          tol: float = 1e-7) -> Judgement:
    """Coverage and footprint of ``setup`` as an outside evaluation measures them."""
    pts, normals = visible_points(view, scene, samples)
    if light.type == "SPOT":  # points outside the cone are unlit: no map needs them
        cos = np.einsum("ij,j->i", light.rays_to(pts), light.direction)
        lit = cos >= np.cos(light.spot_angle / 2)
        pts, normals = pts[lit], normals[lit]
    idx = setup.map_index(pts, view, tol)
    covered = idx >= 0
    cpts, owner = caster_points(pts, light, scene)
    bad_caster = np.zeros(len(cpts), dtype=bool)
    bad_order = np.zeros(len(cpts), dtype=bool)
    for i, m in enumerate(setup.maps):
        sel = idx[owner] == i
        if not sel.any():
            continue
        inside = m.contains(cpts[sel], tol)
        bad_caster[sel] = ~inside
        dc, dr = m.stored_depth(cpts[sel])[0], m.stored_depth(pts[owner[sel]])[0]
        nearer = dc < dr if m.depth_test == "LESS" else dc > dr
        gap = np.abs(dc - dr) > 1e-12
        bad_order[sel] = inside & gap & ~nearer
    fp = setup_texel_footprint(view, setup, pts[covered], normals[covered])
    fp = fp[np.isfinite(fp)]
    return Judgement(
        visible=len(pts), uncovered=int((~covered).sum()), casters=len(cpts),
        casters_uncovered=int(bad_caster.sum()), depth_order_wrong=int(bad_order.sum()),
        footprint_p95=float(np.percentile(fp, 95)) if len(fp) else float("nan"),
        footprint_max=float(fp.max()) if len(fp) else float("nan"),
    )
