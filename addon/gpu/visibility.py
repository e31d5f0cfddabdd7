"""What the camera sees, from the frame's own depth pre-pass.

The render engine draws the camera's depth pre-pass first
(``ShadowFrame.camera_prepass``), reads it back and reduces it per tile to the
nearest and farthest window depth seen there
(``addon.warp.visibility.region_from_window_depth``), so the warp computed next
is fitted to exactly the pixels the shading pass will shade (Lauritzen et al.,
*Sample Distribution Shadow Maps*, I3D 2011; Scherzer §4.4's Δz from
visibility). The shading pass then tests against the same depth target.
"""
from __future__ import annotations

import time

from ..warp.visibility import PIXEL_TILE, VisibleRegion, region_from_window_depth
from . import compose


def region_from_frame(frame, tile: int = PIXEL_TILE, source: str = "depth pre-pass") -> tuple[VisibleRegion, float]:
    """The visible region of ``frame.view`` from the frame's camera pre-pass
    (drawn now if it was not), and the seconds the read-back and reduction
    took: the depth target read back whole into a preallocated array (0.2 ms
    at 640x360, 1-2 ms at 1920x1080 on llvmpipe, shared notes §2), then one
    min and one max per tile in numpy."""
    depth = frame.camera_prepass()
    t = time.perf_counter()
    window = compose.read_depth(frame.targets.framebuffer(depth=depth), frame.size)
    region = region_from_window_depth(frame.view, window, tile, source)
    return region, time.perf_counter() - t
