"""A shadow map evaluated exactly by ray casting, without the GPU.

A shadow map stores, per texel, the depth of the first surface on the light ray
through the texel's centre, and a point is in shadow when that surface is nearer
the light than the point (minus a bias). This module does exactly that with the
ground truth's BVH instead of rasterization: for each visible point p, take the
texel its map projects it into, the light ray through that texel's centre at p's
own map depth (point q), and cast it from the light towards q. Nearest-texel
lookup, no filtering: what a GPU shadow map with NEAREST sampling computes, minus
rasterization's own rounding. The report uses it when the GPU pipeline is not
available, and to cross-check it.

Bias: slope-scaled, ``bias = k·s·tan(α) + c`` in world units along the light ray,
with s the world length of one texel on the surface in its worst direction,
α the angle between the normal and the light, k = 1 (q is within half a texel
diagonal of p) and c = 1e-4 of the scene size (Scherzer §4.2's constant and
slope-scale biases).
"""
from __future__ import annotations

import time

import numpy as np

from addon.measure.footprint import raster_jacobian, tangent_basis
from addon.warp.geometry import homogeneous
from addon.warp.types import Light, ShadowSetup, View


def evaluate(setup: ShadowSetup, view: View, light: Light, bvh, points, normals, scene_scale: float,
             slope_bias: float = 1.0):
    """Shadow (True) per point, the serving map index (-1: none -> lit, as the
    shader treats points outside every map) and the seconds taken."""
    from mathutils import Vector
    t0 = time.perf_counter()
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    nrm = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    idx = setup.map_index(p, view)
    shadow = np.zeros(len(p), dtype=bool)
    c_bias = 1e-4 * scene_scale
    ray_cast = bvh.ray_cast
    for i, m in enumerate(setup.maps):
        sel = np.flatnonzero(idx == i)
        if len(sel) == 0:
            continue
        ps = p[sel]
        h = homogeneous(ps) @ m.matrix.T
        ndc = h[:, :3] / h[:, 3:4]
        size = np.array(m.size, dtype=np.float64)
        texel = np.clip(np.floor((ndc[:, :2] + 1) / 2 * size), 0, size - 1)
        centre = (texel + 0.5) / size * 2 - 1
        q_h = np.column_stack([centre, ndc[:, 2], np.ones(len(sel))]) @ np.linalg.inv(m.matrix).T
        q = q_h[:, :3] / q_h[:, 3:4]
        hj = raster_jacobian(m.matrix, m.size, ps) @ tangent_basis(nrm[sel])
        sv = np.linalg.svd(hj, compute_uv=False)
        with np.errstate(divide="ignore"):
            texel_len = np.where(sv[:, 1] > 0, 1.0 / sv[:, 1], np.inf)
        to_l = (-np.broadcast_to(light.direction, ps.shape) if light.is_directional
                else light.position - ps)
        to_l = to_l / np.linalg.norm(to_l, axis=1, keepdims=True)
        cos_a = np.clip(np.einsum("ij,ij->i", nrm[sel], to_l), 1e-3, 1.0)
        tan_a = np.minimum(np.sqrt(1 - cos_a ** 2) / cos_a, 20.0)
        bias = slope_bias * np.minimum(texel_len, scene_scale) * tan_a + c_bias
        if light.is_directional:
            reach = 4.0 * scene_scale
            d = light.direction
            origins = q - d * reach
            lengths = np.full(len(sel), reach)
            dirs = np.broadcast_to(d, q.shape)
        else:
            v = q - light.position
            lengths = np.linalg.norm(v, axis=1)
            dirs = v / lengths[:, None]
            origins = np.broadcast_to(light.position, q.shape)
        for k, (o, dv, L, b) in enumerate(zip(origins.tolist(), dirs.tolist(), lengths.tolist(), bias.tolist())):
            if L - b <= 0:
                continue
            loc, _, _, _ = ray_cast(Vector(o), Vector(dv), L - b)
            if loc is not None:
                shadow[sel[k]] = True
    return shadow, idx, time.perf_counter() - t0


def depth_preview(setup_map, light: Light, bvh, scene_scale: float, size: int = 128) -> np.ndarray:
    """A (size, size) picture of one map's stored depth (NDC z of the first hit,
    +1 = nothing), sampled at ``size``² texel centres by ray casting (row 0 bottom)."""
    from mathutils import Vector
    m = setup_map.matrix
    inv = np.linalg.inv(m)
    c = (np.arange(size) + 0.5) / size * 2 - 1
    X, Y = np.meshgrid(c, c)
    out = np.ones((size, size))
    pts = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size), np.ones(X.size)]) @ inv.T
    q = pts[:, :3] / pts[:, 3:4]        # a point on each texel centre's light ray
    if light.is_directional:
        reach = 4.0 * scene_scale
        dirs = np.broadcast_to(light.direction, q.shape)
        origins = q - light.direction * reach
        lengths = np.full(len(q), 2 * reach)
    else:
        v = q - light.position
        dirs = v / np.linalg.norm(v, axis=1, keepdims=True)
        origins = np.broadcast_to(light.position, q.shape)
        lengths = np.full(len(q), 4.0 * scene_scale)
    flat = out.ravel()
    for k, (o, dv, L) in enumerate(zip(origins.tolist(), dirs.tolist(), lengths.tolist())):
        loc, _, _, _ = bvh.ray_cast(Vector(o), Vector(dv), L)
        if loc is not None:
            h = m @ np.array([loc[0], loc[1], loc[2], 1.0])
            flat[k] = h[2] / h[3] if setup_map.depth_row is None else float(setup_map.depth_row @ [*loc, 1.0])
    return flat.reshape(size, size)
