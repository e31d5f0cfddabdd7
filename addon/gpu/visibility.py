"""What the camera sees, from the frame's own depth pre-pass.

The render engine draws the camera's depth pre-pass first
(``ShadowFrame.camera_prepass``), reduces it on the GPU per 16 x 16-pixel tile
to the least and greatest window depth drawn there and how many pixels were
(``compose.reduce_blocks``: one pass, a few thousand texels read back), and
turns that into a :class:`~addon.warp.visibility.VisibleRegion`
(``region_from_window_tiles``), so the warp computed next is fitted to exactly
the pixels the shading pass will shade (Lauritzen et al., *Sample Distribution
Shadow Maps*, I3D 2011; Scherzer §4.4's Δz from visibility). The shading pass
then tests against the same depth target. ``bench/visibility.py`` times it.
"""
from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from ..warp.aliasing import pixel_density_constant, raster_jacobian
from ..warp.geometry import raster_position
from ..warp.visibility import (PIXEL_TILE, VisibleRegion, region_from_window_depth, region_from_window_tiles,
                               surface_from_window_depth)
from . import compose
from .result import unpack_normals


def region_from_frame(frame, tile: int = PIXEL_TILE, source: str = "depth pre-pass",
                      on_gpu: bool = True, surface: bool = False) -> tuple[VisibleRegion, float]:
    """The visible region of ``frame.view`` from the frame's camera pre-pass
    (drawn now if it was not), and the seconds it took. ``on_gpu``: reduce the
    tiles on the GPU and read back only them; else read the whole depth target
    back and reduce in numpy (the reference; slower from 1280x720 on).
    ``surface``: also read the whole depth and surface targets back for ``VisibleRegion.surface``
    and ``normals`` (the seen pixels themselves, which plane_optimal's default planes and the
    cascade's maps are chosen by)."""
    depth = frame.camera_prepass()
    t = time.perf_counter()
    if on_gpu:
        blocks = compose.reduce_blocks(frame.targets, depth, frame.size, tile, channel=0, above=-1.0, below=1.0,
                                       depth_source=True, name="visible_tiles")
        region = region_from_window_tiles(frame.view, blocks[..., 0], blocks[..., 1], blocks[..., 2], frame.size,
                                          tile, source)
    else:
        window = compose.read_depth(frame.targets.framebuffer(depth=depth), frame.size)
        region = region_from_window_depth(frame.view, window, tile, source)
    if surface:
        window = window if not on_gpu else compose.read_depth(frame.targets.framebuffer(depth=depth), frame.size)
        seen = frame.targets.framebuffer(colors=(frame.targets.texture("surface", frame.size, "RGBA32F"),))
        points, codes = surface_from_window_depth(frame.view, window, compose.read_color(seen, 0, frame.size)[..., 3])
        region = replace(region, surface=points, normals=unpack_normals(codes))
    return region, time.perf_counter() - t


EDGE_MAP = 512
"""Texels a side of the first look's uniform map(s) (:func:`shadow_edges`)."""
EDGE_PIXELS = 0.5
"""The narrowest band on screen an edge sample of :func:`shadow_edges` is taken to stand for, in pixels."""
EDGE_DISC = 4
"""The radius in texels of the disc of taps whose gradient gives an edge sample its edge's rough normal
(:func:`edge_normals`)."""
DISC = np.array([(x, y) for y in range(-EDGE_DISC, EDGE_DISC + 1) for x in range(-EDGE_DISC, EDGE_DISC + 1)
                 if x * x + y * y <= EDGE_DISC * EDGE_DISC + EDGE_DISC], dtype=np.int64)
"""(T, 2): the taps of :data:`EDGE_DISC`, offsets (x, y) in texels from the sample's texel."""
EDGE_RUN, EDGE_ACROSS = 12, 3
"""Texels each way along the rough edge, and across it, of the taps whose line fit turns it (:func:`edge_normals`)."""
EDGE_GRAZING = 0.05
"""Surface samples whose n·l is below this are left out of :func:`shadow_edges` (turned from the light, or so nearly
edge-on that a coarse map's texel holds the plane itself at many depths)."""


def shadow_edges(frame, region: VisibleRegion, body, light, bounds, options) -> VisibleRegion:
    """``region`` with ``TileDepths.edges``, where a shadow edge can fall on what the camera sees (docs/papers.md,
    "The λ guard", part 7): per tile, the length in pixels (up to a constant) of the shadow edges of a first, coarse
    look, the uniform map(s) of ``body`` at ``EDGE_MAP``² drawn with the frame's casters
    (``ShadowFrame.probe_depths``): its surface samples at an edge (``at_shadow_edge``), each over the width on
    screen of the band of texels that found it; and ``VisibleRegion.edge_directions``, each edge sample's shadow edge
    as a world direction on its surface (``at_shadow_edge``). Unchanged where the surface was not read back or nothing
    casts."""
    if region.surface is None or region.normals is None or not frame.geometry.instances.casts.any():
        return region
    from ..warp import compute
    setup = compute("uniform", frame.view, light, bounds, replace(options, shadow_map_size=(EDGE_MAP, EDGE_MAP)),
                    body=body)
    points = region.surface.mean(axis=1)
    seen_from = -frame.view.direction[None] if frame.view.orthographic else frame.view.position - points
    normals = region.normals * np.sign(np.einsum("ij,ij->i", region.normals, seen_from))[:, None]   # the seen side
    band, free, along = np.zeros(len(points)), np.ones(len(points), dtype=bool), np.zeros((len(points), 3))
    for m, depth in zip(setup.maps, frame.probe_depths(setup, body)):
        mine = free & m.contains(points)
        free &= ~mine
        band[mine], along[mine] = at_shadow_edge(m, depth, points[mine], normals[mine], light)
    view = frame.view
    pixels = band * math.sqrt(pixel_density_constant(view)) / (1.0 if view.orthographic else view.eye_depth(points))
    h = points @ view.world_to_clip[:, :3].T + view.world_to_clip[:, 3]
    t = region.tiles
    col = np.clip(np.searchsorted(t.x_edges[1:-1], h[:, 0] / h[:, 3], side="right"), 0, len(t.x_edges) - 2)
    row = np.clip(np.searchsorted(t.y_edges[1:-1], h[:, 1] / h[:, 3], side="right"), 0, len(t.y_edges) - 2)
    edges = np.bincount(row * t.near.shape[1] + col, np.where(band > 0, 1.0 / np.maximum(pixels, EDGE_PIXELS), 0.0),
                        minlength=t.near.size)
    return replace(region, tiles=replace(t, edges=edges.reshape(t.near.shape)), edge_directions=along)


def at_shadow_edge(shadow_map, window_depth: np.ndarray, points: np.ndarray, normals: np.ndarray,
                   light) -> tuple[np.ndarray, np.ndarray]:
    """Where (N, 3) ``points`` (unit ``normals`` on their seen side, inside ``shadow_map``'s clip volume, n·l >=
    ``EDGE_GRAZING``) lie at one of its shadow edges, the world width of the 3 x 3 texels around each, 0 elsewhere:
    some but not all of them hold a caster nearer the light than the point's own plane where the light ray through
    the texel's centre meets it (the shading's receiver-plane test, ``gpu_shaders/shade_frag.glsl``), by more than
    1.5 texel widths. And (N, 3) the edge's unit direction on each point's plane (0 elsewhere): with g its normal in
    texels (:func:`edge_normals`), the edge runs along d = n × D_Mᵀg (D_M·d ⟂ g, n·d = 0)."""
    m = shadow_map.matrix
    to_light = -light.direction[None] if light.is_directional else light.position - points
    to_light = to_light / np.linalg.norm(to_light, axis=1, keepdims=True)
    j = np.linalg.norm(raster_jacobian(m, shadow_map.size, points), axis=2)      # texels per metre, each way
    width = 1.0 / np.sqrt(j[:, 0] * j[:, 1])
    size = np.array([int(v) for v in shadow_map.size])
    place = raster_position(m, size, points)
    taps = np.floor(place).astype(np.int64)[:, None] + np.stack(np.meshgrid([-1, 0, 1], [-1, 0, 1]), -1).reshape(-1, 2)
    stored = window_depth[np.minimum(np.maximum(taps[..., 1], 0), size[1] - 1),
                          np.minimum(np.maximum(taps[..., 0], 0), size[0] - 1)]
    depth, slope = shadow_map.stored_depth(points)
    cos = np.einsum("ij,ij->i", normals, to_light)
    along = np.abs(np.einsum("ij,ij->i", slope, to_light))
    reach = 3.0 * along * np.sqrt(np.maximum(1.0 - cos * cos, 0.0)) / np.maximum(cos, 1e-6) / j.min(axis=1)
    out, direction = np.zeros(len(points)), np.zeros((len(points), 3))   # only where a tap nearer than the plane
    some = np.flatnonzero(                                                 # can come over 2 texels:
        (cos >= EDGE_GRAZING) & (stored.min(axis=1) < 0.5 * (depth - reach) + 0.5))
    if len(some):
        def held(k, at):
            return _edge_test(shadow_map, window_depth, at, points[k], normals[k], depth[k], 1.5 * width[k] * along[k])
        near = held(some, taps[some]).sum(axis=1)
        k = some[(near > 0) & (near < 9)]
        out[k] = 3.0 * width[k]
        d = np.cross(normals[k], np.einsum("kij,ki->kj", raster_jacobian(m, size, points[k]),
                                           edge_normals(lambda at: held(k, at), place[k])))
        length = np.linalg.norm(d, axis=1, keepdims=True)
        direction[k] = np.where(length > 0, d / np.where(length > 0, length, 1.0), 0.0)
    return out, direction


def edge_normals(held, place: np.ndarray) -> np.ndarray:
    """(K, 2) the normals in texels, toward the casters, of the shadow edges at K edge samples at raster ``place``s;
    ``held``: (K, T, 2) texels -> (K, T), 1 where a texel holds a caster nearer than the sample's plane
    (``at_shadow_edge``'s test). First the gradient over the disc of :data:`EDGE_DISC` texels about each sample's
    texel, g₀ = Σ (s_q − s̄)·q (``addon.measure.footprint.shadow_edge_normals``' on the screen): the rough normal n₀,
    t₀ it turned by 90°. Then the texels at place + u·t₀ + v·n₀, |u| <= :data:`EDGE_RUN`, |v| <= ``EDGE_ACROSS``:
    where each column u that the edge crosses turns from lit to caster, δ(u) = const − Σ_v s, fitted with a line
    δ = a + b·u, turns it, g = n₀ − b·t₀. An edge θ off a texel axis is a staircase that steps once in 1/tan θ texels,
    so only a run that long tells it from one along the axis: the 3 x 3 taps' binary Sobel gradient is exact at 0°,
    45° and 90° only (a 5° edge read as 0°, 18° or 27°), the disc alone errs by up to 7° at 2-5°, the fit by 2°
    (``tests/blender/test_first_look_directions.py``)."""
    ones = held(np.floor(place)[:, None].astype(np.int64) + DISC[None])
    g = (ones - ones.mean(axis=1, keepdims=True)) @ DISC
    n = g / np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-300)
    t = n @ np.array([[0.0, 1.0], [-1.0, 0.0]])
    u, v = np.arange(-EDGE_RUN, EDGE_RUN + 1.0), np.arange(-EDGE_ACROSS, EDGE_ACROSS + 1.0)
    at = np.floor(place[:, None, None] + u[:, None, None] * t[:, None, None] + v[:, None] * n[:, None, None])
    columns = held(at.astype(np.int64).reshape(len(place), len(u) * len(v), 2)).reshape(at.shape[:3]).sum(axis=2)
    crossed = (columns > 0) & (columns < len(v))
    du = np.where(crossed, u - (crossed * u).sum(axis=1, keepdims=True) / np.maximum(crossed.sum(axis=1), 1)[:, None],
                  0.0)
    spread = (du * du).sum(axis=1)
    b = np.where((crossed.sum(axis=1) >= 3) & (spread > 0), -(du * columns).sum(axis=1) / np.maximum(spread, 1e-300),
                 0.0)
    return n - b[:, None] * t


def _edge_test(shadow_map, window_depth, taps, points, normals, depth, bias) -> np.ndarray:
    """:func:`at_shadow_edge`'s test at (K, T, 2) texels ``taps`` (clamped to the map) of K points: (K, T) 1 where the
    texel holds a caster nearer the light than the point's plane, else 0."""
    m, size = shadow_map.matrix, np.array([int(v) for v in shadow_map.size])
    taps = np.minimum(np.maximum(taps, 0), size - 1)
    stored = window_depth[taps[..., 1], taps[..., 0]]
    ndc = (taps + 0.5) * (2.0 / size) - 1.0
    inverse = np.linalg.inv(m)
    start = ndc @ inverse[:, :2].T + inverse[:, 3]                         # each tap's ray at NDC depth 0 and 1
    ends = [h[..., :3] / h[..., 3:] for h in (start, start + inverse[:, 2])]
    ray = ends[1] - ends[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.einsum("ij,ij->i", points, normals)[:, None] - np.einsum("ikj,ij->ik", ends[0], normals)
        on_plane = ends[0] + (t / np.einsum("ikj,ij->ik", ray, normals))[..., None] * ray
    plane = np.where(np.isfinite(on_plane).all(-1), shadow_map.stored_depth(on_plane.reshape(-1, 3))[0].reshape(
        taps.shape[:2]), depth[:, None])
    return (stored < 0.5 * (np.minimum(plane, depth[:, None]) - bias[:, None]) + 0.5).astype(np.float64)
