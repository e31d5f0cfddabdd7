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

import time
from dataclasses import replace

import numpy as np

from ..warp.visibility import (PIXEL_TILE, VisibleRegion, region_from_window_depth, region_from_window_tiles,
                               surface_from_window_depth)
from . import compose


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
        region = replace(region, surface=points, normals=unpacked_normals(codes))
    return region, time.perf_counter() - t


def unpacked_normals(codes: np.ndarray) -> np.ndarray:
    """(N, 3) unit normals from the pre-pass's packed octahedral codes (``prepass_frag.glsl``; as
    ``lixel_unpack_normal`` and ``lixel_unoctahedral`` in ``shade_frag.glsl``: Cigolle et al., JCGT 2014)."""
    v = np.ascontiguousarray(codes, dtype=np.float32).view(np.uint32)
    p = np.stack([(v >> 15) & 16383, v & 32767], axis=-1) * (2.0 / np.array([16383.0, 32767.0])) - 1.0
    n = np.concatenate([p, 1.0 - np.abs(p).sum(axis=-1, keepdims=True)], axis=-1)
    t = np.maximum(-n[..., 2:], 0.0)
    n[..., :2] += np.where(n[..., :2] >= 0.0, -t, t)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)
