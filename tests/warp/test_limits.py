"""Extreme but valid inputs to the warp core (issue: the CLI's limits): a right answer or a clear message, never an
out-of-memory kill. The coarse ray cast's memory stays bounded however many boxes each of its squares sees."""
import tracemalloc

import numpy as np

from addon.warp import region_from_boxes
from addon.warp.types import SceneBounds, View


def cloud_seen_end_on(n: int, seed: int = 1) -> tuple[View, SceneBounds]:
    """``n`` long boxes seen end-on by a camera on their axis: each is deep (near to far) and covers many of the ray
    cast's squares, every square sees hundreds (the (square, box) pairs grow as n times the squares)."""
    rng = np.random.default_rng(seed)
    centre = np.column_stack([rng.uniform(-10, 10, n), rng.uniform(0, 1000, n), rng.uniform(-10, 10, n)])
    half = np.column_stack([rng.uniform(2, 6, n), rng.uniform(50, 400, n), rng.uniform(2, 6, n)])
    looks_along_y = [[1, 0, 0, 0], [0, 0, -1, -30], [0, 1, 0, 0], [0, 0, 0, 1]]
    view = View.perspective(looks_along_y, np.radians(40), 16 / 9, 0.5, 3000, (1280, 720))
    return view, SceneBounds.from_boxes(np.stack([centre - half, centre + half], axis=1))


def peak_bytes(view, scene) -> tuple[int, object]:
    tracemalloc.start()
    try:
        region = region_from_boxes(view, scene)
        return tracemalloc.get_traced_memory()[1], region
    finally:
        tracemalloc.stop()


def test_the_coarse_ray_cast_takes_bounded_memory_however_many_boxes_a_square_sees():
    """3,000 deep boxes over the whole image (~2M (square, box) pairs) peaked at 1.3 GB (tracemalloc) when every pair was held at once;
    taken in chunks the peak stays under 100 MB and about that of 750 boxes."""
    big, region = peak_bytes(*cloud_seen_end_on(3000))
    small, _ = peak_bytes(*cloud_seen_end_on(750))
    assert not region.is_empty
    assert big < 100e6, f"{big / 1e6:.0f} MB"
    assert big < 2 * small + 20e6, (big / 1e6, small / 1e6)
