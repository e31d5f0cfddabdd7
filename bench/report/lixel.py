"""Lixel's frame as the report measures it: the render engine's own frame
(``addon.render.engine.render_depsgraph``: geometry from the cache, the scene
described, B and the warp, then ``render_shadows``: upload, depth pass,
shading, read-back, compose), timed from its start to the pixels in memory.

This module is the one place where the report reads the pipeline's result, so
a change of its type touches only :func:`frame`. The timed frames
(:func:`timed_frame`) are the engine's F12 frames; the measured ones
(:func:`frame`) also read back what the report compares and time each stage.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Optional

import numpy as np

SHADOW_THRESHOLD = 0.5
"""A pixel counts as shadowed when the shadow mask is at least this (PCF 1x1 gives 0 or 1)."""
READ = frozenset({"shadow_raw", "covered", "world_position", "map_index", "combined", "shadow_maps"})
"""The images the report reads back from each frame (``addon.gpu.result.RenderResult`` names)."""


def report_settings(method: str, size: int):
    """The settings every Lixel point of the report uses: the defaults of a fresh
    scene, with the method, one ``size``² texel budget and hard 1x1 PCF (the
    report compares hard shadows with exact ray-cast ones)."""
    from addon.settings import LixelSettings
    base = LixelSettings()
    return replace(base, method=method, warp=replace(base.warp, shadow_map_size=(int(size), int(size))),
                   shadow=replace(base.shadow, pcf_kernel=1))


@dataclass
class LixelFrame:
    """One rendered frame, images (H, W) with row 0 at the bottom."""

    setup: object                   # addon.warp.types.ShadowSetup
    method: str                     # the method that ran (the engine may substitute one)
    shadow: np.ndarray              # bool: shadowed
    covered: np.ndarray             # bool: a surface is drawn
    world_position: np.ndarray      # (H, W, 3) float64, NaN off-surface
    map_index: np.ndarray           # int: the map that served the pixel, -1 none
    combined: np.ndarray            # (H, W, 3) linear radiance
    shadow_maps: list               # window depth per map (H_m, W_m)
    seconds: float                  # wall clock of the whole frame
    cpu_seconds: float              # process CPU time of the whole frame (every thread)
    stages: dict = field(default_factory=dict)   # the engine's own stage times (seconds)
    warnings: list = field(default_factory=list)
    world_normal: Optional[np.ndarray] = None   # (H, W, 3) the surface's normal, NaN off-surface (crease pixels)


def timed_frame(depsgraph, settings, resolution) -> tuple[float, float]:
    """(wall seconds, process CPU seconds) of one frame exactly as the LIXEL
    engine renders for F12: no wait for the GPU between stages, and only the
    engine's own passes read back. Python's garbage collector is held off for
    the frame (as ``timeit`` does); what it would collect is collected before."""
    import gc
    from addon.render.engine import render_depsgraph
    from .timing import Clocks
    gc.collect()
    gc.disable()
    try:
        start = Clocks.now()
        render_depsgraph(depsgraph, tuple(int(v) for v in resolution), settings, warnings=[], timed=False)
        return start.since()
    finally:
        gc.enable()


def frame(depsgraph, settings, resolution) -> LixelFrame:
    """Render the depsgraph's scene from its camera, as the LIXEL engine does,
    reading back what the report measures (:data:`READ`) and waiting for the
    GPU after each stage so that each stage's time is its own."""
    from addon.render.engine import render_depsgraph
    from .timing import Clocks
    warnings: list = []
    start = Clocks.now()
    out = render_depsgraph(depsgraph, tuple(int(v) for v in resolution), settings, warnings=warnings, read=READ)
    seconds, cpu_seconds = start.since()
    res = out["result"]
    return LixelFrame(
        setup=out["setup"], method=out["method"],
        shadow=np.asarray(res.shadow_raw) >= SHADOW_THRESHOLD,
        covered=np.asarray(res.covered, dtype=bool),
        world_position=np.asarray(res.world_position, dtype=np.float64),
        world_normal=None if res.world_normal is None else np.asarray(res.world_normal, dtype=np.float64),
        map_index=np.asarray(res.map_index),
        combined=np.asarray(res.combined)[..., :3],
        shadow_maps=list(res.shadow_maps),
        seconds=seconds, cpu_seconds=cpu_seconds, stages={k: float(v) for k, v in res.timings.items()},
        warnings=warnings)
