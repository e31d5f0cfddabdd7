"""Exact hard shadows for every pixel by ray casting (the report's ground truth).

For each pixel centre the camera ray's first hit in a ``mathutils.bvhtree.BVHTree``
of the evaluated scene's triangles is the visible point; a second ray from that
point towards the light decides lit or shadowed. This is exact (up to the float32
BVH) for hard shadows, whatever the shadow-map method.

Pixel convention: images are (H, W) with row 0 at the *bottom*, like Blender's
render results and OpenGL read-back; pixel (x, y) has NDC centre
((2x + 1)/W - 1, (2y + 1)/H - 1).

``valid`` marks the pixels the error metrics count: a surface is visible, it faces
the light (a surface turned away is dark whatever the shadow test says) and, for
a spot light, it lies inside the cone.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from addon.measure.box_scene import pixel_rays
from addon.warp.types import Light, View


@dataclass
class Triangles:
    """World-space triangles of an evaluated scene: (T, 3, 3) float64."""

    tris: np.ndarray
    seconds: float = 0.0

    def __len__(self) -> int:
        return len(self.tris)


def world_triangles(geometry) -> Triangles:
    """Every triangle of an ``addon.scene.geometry.SceneGeometry`` (what the gpu
    pipeline draws: real objects and GN instances) in world space."""
    t0 = time.perf_counter()
    inst = geometry.instances
    by_key: dict = {}
    for i, key in enumerate(inst.keys):
        by_key.setdefault(key, []).append(i)
    parts = []
    for key, rows in by_key.items():
        mesh = geometry.meshes[key]
        tri = np.asarray(mesh.positions, dtype=np.float64)[mesh.triangles]      # (t, 3, 3) local
        mats = inst.matrices[rows]                                              # (k, 4, 4)
        w = np.einsum("kij,tvj->ktvi", mats[:, :3, :3], tri) + mats[:, None, None, :3, 3]
        parts.append(w.reshape(-1, 3, 3))
    tris = np.concatenate(parts) if parts else np.zeros((0, 3, 3))
    return Triangles(tris, time.perf_counter() - t0)


def scene_triangles(depsgraph) -> Triangles:
    """World triangles of the evaluated scene, read by the scene layer's own
    extraction (``addon.scene.geometry``) so the ground truth sees exactly what
    the pipeline draws."""
    from addon.scene.geometry import GeometryCache
    return world_triangles(GeometryCache().update(depsgraph))


def build_bvh(tris: Triangles):
    from mathutils.bvhtree import BVHTree
    t = tris.tris
    verts = t.reshape(-1, 3).tolist()
    polys = np.arange(len(verts), dtype=np.int64).reshape(-1, 3).tolist()
    return BVHTree.FromPolygons(verts, polys, all_triangles=True, epsilon=0.0)


@dataclass
class GroundTruth:
    """Per-pixel ground truth, (H, W) arrays with row 0 at the bottom."""

    hit: np.ndarray          # bool: a surface is visible
    points: np.ndarray       # (H, W, 3) visible point (NaN where no hit)
    normals: np.ndarray      # (H, W, 3) unit geometric normal facing the camera
    shadow: np.ndarray       # bool: the point is in shadow (or faces away from the light)
    valid: np.ndarray        # bool: counted by the metrics (hit, faces the light, inside a spot cone)
    camera: np.ndarray = field(default_factory=lambda: np.zeros(3))   # the camera position
    timings: dict = field(default_factory=dict)

    @property
    def shape(self):
        return self.hit.shape


def _to_light(light: Light, p: np.ndarray):
    """Unit directions from points towards the light and the distances to it (inf for a sun)."""
    if light.is_directional:
        d = np.broadcast_to(-light.direction, p.shape).copy()
        return d, np.full(len(p), np.inf)
    d = light.position - p
    dist = np.linalg.norm(d, axis=1)
    return d / dist[:, None], dist


def direct_light(points: np.ndarray, normals: np.ndarray, light: Light, albedo: float,
                 spot_blend: float = 0.0) -> np.ndarray:
    """Unshadowed direct radiance of a grey diffuse surface, the formula of
    Lixel's shading pass (gpu_shaders/shade_frag.glsl, mirrored here so the
    ground truth is shaded exactly like Lixel's renders): colour · energy ·
    irradiance · n·l · albedo / π, irradiance 1 for a sun and 1 / (4π r²) for
    a point or spot, a spot's cone edge smoothed over ``spot_blend`` (Blender's
    spot mask). ``points``/``normals`` (..., 3); NaN points give 0."""
    p = np.asarray(points, dtype=np.float64)
    flat = p.reshape(-1, 3)
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    out = np.zeros(len(flat))
    ok = np.all(np.isfinite(flat), axis=1)
    q = flat[ok]
    if light.is_directional:
        to_l = np.broadcast_to(-light.direction, q.shape)
        irradiance = np.ones(len(q))
    else:
        d = light.position - q
        r2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-12)
        to_l = d / np.sqrt(r2)[:, None]
        irradiance = 1.0 / (4.0 * math.pi * r2)
        if light.type == "SPOT":
            cos_half = math.cos(light.spot_angle / 2)
            x = np.einsum("ij,j->i", -to_l, light.direction) - cos_half
            blend = spot_blend * (1.0 - cos_half)
            if blend > 0:
                u = np.clip(x / blend, 0.0, 1.0)
                irradiance *= u * u * (3.0 - 2.0 * u)
            else:
                irradiance *= (x >= 0).astype(np.float64)
    ndl = np.maximum(np.einsum("ij,ij->i", n[ok], to_l), 0.0)
    grey = float(np.dot(light.color, (0.2126, 0.7152, 0.0722))) * light.energy
    out[ok] = grey * irradiance * ndl * albedo / math.pi
    return out.reshape(p.shape[:-1])


def _occluded(ray_cast, o, d, limit: float, p, n, eps: float) -> bool:
    """Whether the segment from ``o`` along unit ``d`` for ``limit`` hits a surface other than the receiver's own
    plane (through ``p`` with unit normal ``n``: parallel to it and within ``eps`` of it), passing over those
    (``mathutils.Vector`` arguments)."""
    for _ in range(OWN_PLANE_HITS):
        loc, normal, _, t = ray_cast(o, d, limit)
        if loc is None:
            return False
        if abs(n.dot(loc - p)) > eps or abs(n.dot(normal)) < PARALLEL:
            return True
        o = loc + d * eps
        limit -= t + eps
        if limit <= 0.0:
            return False
    return False


OWN_PLANE_HITS = 64
"""How many hits on the receiver's own plane a shadow ray passes over (float32 rounding along a grazing ray)."""
PARALLEL = 1.0 - 1e-6
"""|cos| between two normals at or above which their surfaces are parallel (1.4e-3 rad)."""


def ground_truth(view: View, light: Light, bvh, scene_scale: float) -> GroundTruth:
    """Cast the camera rays and the shadow rays (see module doc)."""
    from mathutils import Vector
    w, h = view.resolution
    t0 = time.perf_counter()
    origins, dirs, _ = pixel_rays(view, view.resolution)
    n = len(origins)
    pts = np.full((n, 3), np.nan)
    nrm = np.zeros((n, 3))
    hit = np.zeros(n, dtype=bool)
    ray_cast = bvh.ray_cast
    reach = view.far * 4.0
    for i, (o, d) in enumerate(zip(origins.tolist(), dirs.tolist())):
        loc, normal, _, _ = ray_cast(Vector(o), Vector(d), reach)
        if loc is not None:
            hit[i] = True
            pts[i] = loc
            nrm[i] = normal
    t1 = time.perf_counter()
    # keep what the camera sees: eye depth within [near, far]
    depth = np.full(n, np.nan)
    depth[hit] = view.eye_depth(pts[hit])
    hit &= (depth >= view.near) & (depth <= view.far)
    # normals face the camera
    flip = np.einsum("ij,ij->i", nrm, dirs) > 0
    nrm[flip] *= -1
    shadow = np.zeros(n, dtype=bool)
    valid = hit.copy()
    idx = np.flatnonzero(hit)
    p = pts[idx]
    to_l, dist = _to_light(light, p)
    facing = np.einsum("ij,ij->i", nrm[idx], to_l) > 0
    valid[idx[~facing]] = False
    shadow[idx[~facing]] = True
    if light.type == "SPOT":
        inside = np.einsum("ij,j->i", -to_l, light.direction) >= math.cos(light.spot_angle / 2)
        valid[idx[~inside]] = False
        shadow[idx[~inside]] = True
    todo = np.flatnonzero(facing)
    # The shadow ray starts on its own line, eps along it: a start moved along the normal would move the line
    # sideways, and at grazing light (n·l = 0.04: 3.8 mm becomes cm on a wall) pass an occluder's edge on the
    # wrong side. A hit on a surface parallel to the receiver and within eps of its plane is the receiver
    # itself through float32 rounding (the segment leaves the plane at once) and is passed over; any other
    # hit shadows, however near the plane. (Starting eps above the surface, eps / n·l along the ray, skipped
    # those too: at n·l = 5.5e-4 that is 8 m, through a box that stands in the receiver; docs/papers.md.)
    eps = 1e-5 * scene_scale + 2e-5 * np.linalg.norm(p - view.position, axis=1)
    start = p + to_l * eps[:, None]
    limit = np.where(np.isfinite(dist), dist - 2.0 * eps, scene_scale * 4.0)
    for k in todo[limit[todo] > 0].tolist():
        shadow[idx[k]] = _occluded(ray_cast, Vector(start[k].tolist()), Vector(to_l[k].tolist()), float(limit[k]),
                                   Vector(p[k].tolist()), Vector(nrm[idx[k]].tolist()), float(eps[k]))
    t2 = time.perf_counter()
    return GroundTruth(hit=hit.reshape(h, w), points=pts.reshape(h, w, 3), normals=nrm.reshape(h, w, 3),
                       shadow=shadow.reshape(h, w), valid=valid.reshape(h, w), camera=view.position,
                       timings={"camera_rays": t1 - t0, "shadow_rays": t2 - t1})
