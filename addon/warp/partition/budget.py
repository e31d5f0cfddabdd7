"""How a cascade's texels are shared between its maps.

* ``per_map`` (the default, as PSSM does): every map gets the configured
  ``shadow_map_size``; N splits use N times its texels.
* ``shared``: the configured size is the whole budget, shared so that the
  predicted errors come out equal. A map's error falls as one over the side
  of its raster (E ∝ 1/sqrt(texels)), so map i gets texels in proportion to
  E_i², its predicted error at a common size, and all end at
  sqrt(Σ E_j² / T)·side(T) of the per-map error: the least largest error a
  fixed budget allows.
"""
from __future__ import annotations

import numpy as np

BUDGETS = ("per_map", "shared")
SMALLEST_SIDE = 16
"""No shared map is narrower than this many texels."""


def shared_sizes(size: tuple[int, int], errors) -> list[tuple[int, int]]:
    """Each map's (w, h) when the texels of one ``size`` map are shared in
    proportion to the maps' errors squared, each keeping ``size``'s aspect."""
    e = np.asarray(errors, dtype=np.float64)
    e = np.where(np.isfinite(e) & (e > 0), e, np.nanmax(np.where(np.isfinite(e), e, np.nan), initial=1.0))
    share = e * e / float(np.sum(e * e))
    scale = np.sqrt(share)                                   # each side shrinks by sqrt of its share
    w, h = size
    sides = np.stack([np.rint(w * scale), np.rint(h * scale)], axis=1)
    sides = np.clip(sides, SMALLEST_SIDE, 16384).astype(int)
    return [(int(a), int(b)) for a, b in sides]
