"""Full-screen GPU passes after the shading pass, and reading images back.

* :func:`compose_pass`: the combined image after the eye-space blur
  (``gpu_shaders/compose_frag.glsl``; without the blur the shading pass
  writes it itself, with the shadow and the footprint heatmap);
* :func:`eye_blur_pass`: the depth-dependent eye-space blur (Scherzer §4.3);
* :func:`map_preview_pass`: a shadow map resampled to a picture (the render
  engine's "Shadow Map" pass, the viewport's picture-in-picture);
* :func:`reduce_range`: (least, greatest) of a texture channel by repeated
  block reduction, read back as two floats (the nearest eye depth for the
  blur, the written depth range for a preview);
* :func:`read_color` / :func:`read_depth`: float32 read-back into numpy
  (``data=`` a Buffer over a C-ordered array: one copy, no transposition,
  shared notes §2).
"""
from __future__ import annotations

import math

import numpy as np

from . import shaders

REDUCE_BLOCK = 8
"""Source texels per side reduced by one reduction step."""
BIG = 3.0e38


def _buffer(array: np.ndarray):
    import gpu
    return gpu.types.Buffer("FLOAT", array.shape, array)


def read_color(fb, slot: int, size: tuple[int, int], channels: int = 4) -> np.ndarray:
    """(H, W, channels) float32 (or (H, W) for one channel), row 0 at the bottom."""
    w, h = size
    out = np.empty((h, w * channels), dtype=np.float32)
    with fb.bind():
        fb.read_color(0, 0, w, h, channels, slot, "FLOAT", data=_buffer(out))
    return out.reshape(h, w, channels) if channels > 1 else out.reshape(h, w)


def read_depth(fb, size: tuple[int, int]) -> np.ndarray:
    """(H, W) float32 window depth, row 0 at the bottom."""
    w, h = size
    out = np.empty((h, w), dtype=np.float32)
    with fb.bind():
        fb.read_depth(0, 0, w, h, data=_buffer(out))
    return out


def sync(fb, color: bool = False) -> None:
    """Wait for the GPU (no gpu.finish in the API: read one pixel). Mesa's
    llvmpipe finishes only what the read depends on: read colour after a pass
    that writes colour but not depth."""
    with fb.bind():
        if color:
            fb.read_color(0, 0, 1, 1, 4, 0, "FLOAT")
        else:
            fb.read_depth(0, 0, 1, 1)


_fullscreen = None


def fullscreen_batch():
    """One triangle covering the viewport (``fullscreen_vert.glsl``)."""
    global _fullscreen
    if _fullscreen is None:
        from .batches import make_batch
        _fullscreen = make_batch(np.array([(-1, -1, 0), (3, -1, 0), (-1, 3, 0)], np.float32),
                                 np.array([(0, 1, 2)], np.int32))
    return _fullscreen


def _draw_fullscreen(fb, size, shader) -> None:
    import gpu
    with fb.bind():
        gpu.state.viewport_set(0, 0, int(size[0]), int(size[1]))
        gpu.state.depth_test_set("NONE")
        gpu.state.blend_set("NONE")
        fullscreen_batch().draw(shader)


def compose_pass(targets, size, direct, mask, ambient, albedo: float, behind=None):
    """The combined image (an RGBA32F target) after the eye-space blur, from the
    shading pass's unshadowed light ``direct`` and the blurred shadow ``mask``;
    ``behind`` (RGBA) where no surface is seen (default: ``ambient``, alpha 1).
    Returns its framebuffer."""
    combined = targets.texture("combined", size, "RGBA32F")
    fb = targets.framebuffer(colors=(combined,))
    sh = shaders.compose_shader()
    sh.bind()
    sh.uniform_sampler("u_direct", direct)
    sh.uniform_sampler("u_mask", mask)
    sh.uniform_float("u_ambient", (*(float(c) for c in ambient), float(albedo)))
    sh.uniform_float("u_background", tuple(float(c) for c in behind) if behind is not None else (*ambient, 1.0))
    _draw_fullscreen(fb, size, sh)
    return fb


def eye_blur_pass(targets, size, data, radius: float, d_near: float):
    """The eye-space blurred shadow mask (an R32F texture) from the shading pass's ``data``."""
    mask = targets.texture("blurred", size, "R32F")
    fb = targets.framebuffer(colors=(mask,))
    sh = shaders.eye_blur_shader()
    sh.bind()
    sh.uniform_sampler("u_data", data)
    sh.uniform_float("u_blur", (float(radius), float(d_near), 0.0, 0.0))
    _draw_fullscreen(fb, size, sh)
    return mask


def reduce_blocks(targets, source, size, block: int, channel: int = 0, above: float = -BIG, below: float = BIG,
                  depth_source: bool = False, name: str = "reduce_blocks") -> np.ndarray:
    """One reduction step read back: per ``block`` x ``block`` texels of
    ``source`` (the last row and column of blocks partial), (least, greatest,
    count) of its channel over the values strictly between ``above`` and
    ``below``, as a (ceil(h / block), ceil(w / block), 3) array, row 0 at the
    bottom; (+BIG, -BIG, 0) where there are none (e.g. the per-tile window
    depth of a camera pre-pass, ``addon.gpu.visibility``)."""
    w, h = -(-int(size[0]) // block), -(-int(size[1]) // block)
    out = targets.texture(name, (w, h), "RGBA32F")
    fb = targets.framebuffer(colors=(out,))
    sh = shaders.reduce_shader(depth_source)
    sh.bind()
    sh.uniform_sampler("u_source", source)
    sh.uniform_float("u_reduce", (float(channel), float(above), float(below), float(block)))
    _draw_fullscreen(fb, (w, h), sh)
    return read_color(fb, 0, (w, h), 4)[..., :3]


def reduce_range(targets, source, size, channel: int, above: float = -BIG, below: float = BIG,
                 depth_source: bool = False) -> tuple[float, float]:
    """(least, greatest) of ``source``'s channel over the values strictly
    between ``above`` and ``below``; (inf, -inf) when there are none."""
    w, h = int(size[0]), int(size[1])
    step = 0
    src, params, depth = source, (float(channel), float(above), float(below), float(REDUCE_BLOCK)), depth_source
    while True:
        w, h = -(-w // REDUCE_BLOCK), -(-h // REDUCE_BLOCK)
        out = targets.texture(f"reduce{step}", (w, h), "RG32F")
        fb = targets.framebuffer(colors=(out,))
        sh = shaders.reduce_shader(depth)
        sh.bind()
        sh.uniform_sampler("u_source", src)
        sh.uniform_float("u_reduce", params)
        _draw_fullscreen(fb, (w, h), sh)
        if w * h <= 64:
            break
        src, params, depth, step = out, (-1.0, 0.0, 0.0, float(REDUCE_BLOCK)), False, step + 1
    pairs = read_color(fb, 0, (w, h), 2).reshape(-1, 2)
    lo, hi = float(pairs[:, 0].min()), float(pairs[:, 1].max())
    return (lo if lo < BIG / 2 else np.inf), (hi if hi > -BIG / 2 else -np.inf)


def map_picture(targets, name: str, depth_map, map_size, longest: int):
    """The shadow map ``depth_map`` as a grey picture (an RGBA32F texture) at most
    ``longest`` pixels on its longer side, every ``step``-th texel (step =
    ceil(longer side / longest)), stretched over the depths written (near the
    light bright, cleared texels dark blue): ``addon.ui.renders.depth_to_rgba``
    on the GPU."""
    w, h = int(map_size[0]), int(map_size[1])
    step = max(1, math.ceil(max(w, h) / longest))
    size = (-(-w // step), -(-h // step))
    raw, _ = map_preview_pass(targets, name + "_depth", size, depth_map, stretch=False, step=step)
    lo, hi = reduce_range(targets, raw, size, channel=0, below=1.0)
    tex, _ = map_preview_pass(targets, name, size, depth_map, stretch=True,
                              depth_range=(lo, hi) if hi >= lo else (0.0, 1.0), step=step)
    return tex


def map_preview_pass(targets, name: str, size, depth_map, stretch: bool, depth_range=(0.0, 1.0), step: int = 0):
    """``depth_map`` resampled to ``size`` (nearest texel per pixel centre; or,
    ``step`` > 0, every ``step``-th texel from texel 0): its window depth (an
    R32F texture) or, ``stretch``, a grey picture (RGBA32F) stretched over
    ``depth_range``. Returns (texture, framebuffer)."""
    tex = targets.texture(name, size, "RGBA32F" if stretch else "R32F")
    fb = targets.framebuffer(colors=(tex,))
    sh = shaders.map_preview_shader(stretch)
    sh.bind()
    sh.uniform_sampler("u_map", depth_map)
    sh.uniform_float("u_range", (float(depth_range[0]), float(depth_range[1]), float(size[0]), float(size[1])))
    sh.uniform_float("u_step", float(step))
    _draw_fullscreen(fb, size, sh)
    return tex, fb
