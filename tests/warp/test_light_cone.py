"""``frame.light_cone`` divides by the lengths in place when no point
sits at the apex, and equals the construction that always filters the points
near the apex first (random point sets, some with points at the apex)."""
import math

import numpy as np
import pytest

from addon.warp.frame import SURROUND_AXIS, SURROUND_BLEND, light_cone


def plain_light_cone(points, apex):
    """light_cone as written before: the points near the apex always filtered out first."""
    dirs = points - apex
    norms = np.sqrt((dirs * dirs).sum(axis=1))
    farthest = float(norms.max())
    far = norms > 1e-7 * farthest
    dirs = dirs[far] / norms[far, None]
    mid = (dirs.min(axis=0) + dirs.max(axis=0)) / 2
    short = SURROUND_BLEND - np.linalg.norm(mid)
    if short > 0:
        mid = mid + short * SURROUND_AXIS
    axis = mid / np.linalg.norm(mid)
    return axis, math.acos(min(max(float((dirs @ axis).min()), -1.0), 1.0))


@pytest.mark.parametrize("seed", range(3))
def test_light_cone_equals_the_filtered_construction(seed):
    rng = np.random.default_rng(900 + seed)
    at_apex = 0
    for _ in range(60):
        apex = rng.normal(size=3) * 5
        points = apex + rng.normal(size=(int(rng.integers(4, 30)), 3)) * rng.uniform(0.1, 10)
        if rng.random() < 0.4:                           # some points at the apex itself (B has the light as a vertex)
            points[rng.integers(len(points), size=2)] = apex + rng.normal(size=(2, 3)) * 1e-12
            at_apex += 1
        axis, half = light_cone(points, apex)
        plain_axis, plain_half = plain_light_cone(points, apex)
        assert np.allclose(axis, plain_axis, atol=1e-12) and abs(half - plain_half) <= 1e-9
    assert 0 < at_apex < 60
