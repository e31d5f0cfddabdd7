"""Blender's own renderers as peers: the shadow term of EEVEE and of Cycles.

The shadow term is measured as a ratio of two renders of the scene with every
material overridden by one white diffuse material, a black world and only the
scene's one light: the render with shadows divided by the render with the
light's shadows switched off (``Light.use_shadow``). A pixel is in shadow when
the ratio is below 0.5. The reported time is that of the render *with* shadows,
made second so that EEVEE's shader compilation falls on the shadowless one
(which is only our measuring device).

Cycles renders direct light only (no bounces) with one sample and a tiny pixel
filter, which is exact for a sun/spot of zero size. EEVEE's samples are a
parameter (it is slow on llvmpipe: 10-25 s a render at 16 samples).
"""
from __future__ import annotations

import os
import tempfile
import time
from dataclasses import dataclass

import numpy as np

PEERS = ("eevee", "cycles")


def eevee_engine_id() -> str:
    import bpy
    return "BLENDER_EEVEE" if bpy.app.version >= (5, 0, 0) else "BLENDER_EEVEE_NEXT"


@dataclass
class PeerResult:
    shadow: np.ndarray        # (H, W) bool, row 0 at the bottom
    ratio: np.ndarray         # (H, W) shadowed / unshadowed radiance
    lit: np.ndarray           # (H, W) bool: the unshadowed render has light here (ratio is meaningful)
    image: np.ndarray         # (H, W) the shadowed render's luminance
    seconds: float            # time of the render with shadows
    seconds_first: float      # the shadowless render's time (includes EEVEE's shader compilation)


def _override_material(scene):
    """Every surface white diffuse (the sample scenes' material) for the peers' shadow term."""
    from sample_blends.scenes import white_material
    mat = white_material()
    for vl in scene.view_layers:
        vl.material_override = mat


def _render_to_array(scene, path: str) -> tuple[np.ndarray, float]:
    import bpy
    scene.render.filepath = path
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True, scene=scene.name)
    dt = time.perf_counter() - t0
    img = bpy.data.images.load(path, check_existing=False)
    try:
        w, h = img.size
        px = np.empty(w * h * img.channels, dtype=np.float32)
        img.pixels.foreach_get(px)
        px = px.reshape(h, w, img.channels)
    finally:
        bpy.data.images.remove(img)
    lum = 0.2126 * px[..., 0] + 0.7152 * px[..., 1] + 0.0722 * px[..., 2]
    return lum.astype(np.float64), dt


def render_shadow_term(scene, light_obj, peer: str, samples: int = 1) -> PeerResult:
    """Render ``scene`` with ``peer`` ("eevee" or "cycles") twice and return its shadow term.
    The scene's render settings, the light's shadow settings and the view
    layers' material overrides are restored afterwards."""
    import bpy
    r = scene.render
    saved = dict(engine=r.engine, filepath=r.filepath, fmt=r.image_settings.file_format,
                 depth=r.image_settings.color_depth, filter=r.filter_size, use_shadow=light_obj.data.use_shadow,
                 soft=light_obj.data.shadow_soft_size,
                 overrides=[vl.material_override for vl in scene.view_layers])
    tmp = tempfile.mkdtemp(prefix="lixel-peer-")
    try:
        _override_material(scene)
        r.image_settings.file_format = "OPEN_EXR"
        r.image_settings.color_depth = "32"
        r.filter_size = 0.01
        light_obj.data.shadow_soft_size = 0.0
        if getattr(light_obj.data, "angle", None) is not None and light_obj.data.type == "SUN":
            light_obj.data.angle = 0.0
        if peer == "cycles":
            r.engine = "CYCLES"
            c = scene.cycles
            c.device = "CPU"
            c.samples = max(1, int(samples))
            c.use_adaptive_sampling = False
            c.use_denoising = False
            # no Russian roulette on dim light samples: the default light threshold
            # (0.01) terminates shadow rays at random where the light is weak, which
            # makes the shadow term noisy (e.g. under a spot light)
            c.light_sampling_threshold = 0.0
            c.max_bounces = 0
            c.diffuse_bounces = 0
            c.caustics_reflective = c.caustics_refractive = False
            c.pixel_filter_type = "BOX"
            c.filter_width = 0.01
        elif peer == "eevee":
            r.engine = eevee_engine_id()
            e = scene.eevee
            e.taa_render_samples = max(1, int(samples))
            for attr, val in (("use_raytracing", False), ("use_gtao", False), ("use_bloom", False),
                              ("use_shadows", True), ("use_soft_shadows", False)):
                if hasattr(e, attr):
                    setattr(e, attr, val)
        else:
            raise ValueError(f"unknown peer {peer!r}; choose from {', '.join(PEERS)}")
        # the shadowless render goes first: it absorbs EEVEE's shader compilation, so the
        # timed render (with shadows) is a warm one
        light_obj.data.use_shadow = False
        open_, t_first = _render_to_array(scene, os.path.join(tmp, "open.exr"))
        light_obj.data.use_shadow = True
        shadowed, seconds = _render_to_array(scene, os.path.join(tmp, "shadowed.exr"))
        lit = open_ > 1e-4 * max(float(open_.max()), 1e-12)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(lit, shadowed / np.where(lit, open_, 1.0), 1.0)
        return PeerResult(shadow=lit & (ratio < 0.5), ratio=ratio, lit=lit, image=shadowed,
                          seconds=seconds, seconds_first=t_first)
    finally:
        r.engine = saved["engine"]
        r.filepath = saved["filepath"]
        r.image_settings.file_format = saved["fmt"]
        r.image_settings.color_depth = saved["depth"]
        r.filter_size = saved["filter"]
        light_obj.data.use_shadow = saved["use_shadow"]
        light_obj.data.shadow_soft_size = saved["soft"]
        for vl, mat in zip(scene.view_layers, saved["overrides"]):
            vl.material_override = mat
        for f in os.listdir(tmp):
            os.remove(os.path.join(tmp, f))
        os.rmdir(tmp)
