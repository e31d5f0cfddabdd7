"""A cascade's texels: ``per_map`` (PSSM) gives every map ``shadow_map_size``'s texels (square or laid out 2:1,
``methods.cascade.stretched``); ``shared`` shares them so the predicted errors come out equal: E ∝ 1/sqrt(texels), so
map i takes texels ∝ E_i² (the least largest error)."""
from __future__ import annotations

import numpy as np

from ..types import MAX_MAP_SIDE

SMALLEST_SIDE = 16
"""No shared map is narrower than this many texels."""


def shared_sizes(sizes, errors) -> list[tuple[int, int]]:
    """Each map's (w, h): the texels of one of ``sizes`` (each map's, all of one count) ∝ the maps' errors squared,
    each map's aspect kept."""
    e = np.asarray(errors, dtype=np.float64)
    e = np.where(np.isfinite(e) & (e > 0), e, np.nanmax(np.where(np.isfinite(e), e, np.nan), initial=1.0))
    scale = e / np.sqrt(np.sum(e * e))                       # each side ∝ sqrt of its share
    sides = np.clip(np.rint(scale[:, None] * np.asarray(sizes, dtype=np.float64)), SMALLEST_SIDE, MAX_MAP_SIDE).astype(int)
    return [(int(a), int(b)) for a, b in sides]
