"""Numpy-only measurements for the speed-against-error report (no bpy here).

* :mod:`.lloyd`     - Lloyd's physical limit N_min and m_min = sqrt(N_min / N)
* :mod:`.footprint` - texel footprint per pixel (screen pixels per texel) and its statistics
* :mod:`.errors`    - false shadow / false light against ground truth, edge band, flicker, its split and the screen motion it meets
"""
from __future__ import annotations

from .errors import ErrorCounts, Flicker, FlickerSplit, classify, edge_band, error_image, flicker, flicker_split, \
    screen_motion
from .footprint import FootprintStats, footprint_stats, perspective_footprints, setup_footprints
from .lloyd import m_min, n_min, n_min_parallel, n_min_perpendicular

__all__ = ["ErrorCounts", "Flicker", "FlickerSplit", "classify", "edge_band", "error_image", "flicker",
           "flicker_split", "screen_motion", "FootprintStats",
           "footprint_stats", "perspective_footprints", "setup_footprints", "m_min", "n_min", "n_min_parallel",
           "n_min_perpendicular"]
