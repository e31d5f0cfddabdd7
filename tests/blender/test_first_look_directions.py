"""The first look's edge directions (``addon.gpu.visibility.at_shadow_edge``) on a known straight shadow edge.

The cascade's pick and PSM's edge turn prefer maps whose texel axes are turned off the shadow edges
(``partition.receivers.filter_losses``), so an edge a few degrees off the first look's texel axes must read as such,
not as one along them: the 3 x 3 taps' binary Sobel gradient is exact at 0°, 45° and 90° only.
"""
import importlib
import math

import numpy as np
import pytest

SIZE = 512


@pytest.fixture(scope="module")
def mods(lixel):
    """The enabled extension's ``addon.gpu.visibility`` and ``addon.warp.types`` (importing ``addon.gpu`` under a
    second name beside the extension's left the 5.0 test process to crash in its last garbage collection)."""
    return [importlib.import_module(f"{lixel.__name__}.addon.{name}") for name in ("gpu.visibility", "warp.types")]


def sun_above_a_half_plane_caster(types, degrees: float):
    """A sun straight down onto the ground z = 0, its 512² map (``types``: the extension's addon.warp.types) over x, y
    in [-10, 10] m, and the window depths of a caster 2 m up whose edge crosses the map at ``degrees`` from its x axis
    (texels whose centre lies past the line hold it): (map, window depth, unit edge direction, unit normal into the
    caster, a point on the edge)."""
    matrix = np.array([[0.1, 0, 0, 0], [0, 0.1, 0, 0], [0, 0, -0.1, 0.5], [0, 0, 0, 1]], dtype=np.float64)
    a = math.radians(degrees)
    along, across = np.array([math.cos(a), math.sin(a)]), np.array([-math.sin(a), math.cos(a)])
    through = np.array([0.3, -0.2])                                              # metres
    centres = (np.stack(np.meshgrid(np.arange(SIZE), np.arange(SIZE)), -1) + 0.5) / SIZE * 20.0 - 10.0   # (row, col)
    window = np.where((centres - through) @ across > 0, 0.5 * 0.3 + 0.5, 1.0).astype(np.float32)
    return types.ShadowMap(matrix, (SIZE, SIZE)), window, along, across, through


@pytest.mark.parametrize("degrees", [2.0, 5.0, 8.0, 20.0, 33.0])
def test_the_first_look_tells_a_straight_edge_a_few_degrees_off_its_texel_axes_from_one_along_them(mods, degrees):
    """Ground points along the edge, at sub-texel steps along it and across it within half a texel: each is found at
    the edge, and the direction it is given lies within 2.5° of the edge (the median within 1°)."""
    visibility, types = mods
    shadow_map, window, along, across, through = sun_above_a_half_plane_caster(types, degrees)
    texel = 20.0 / SIZE
    s, t = np.meshgrid(np.linspace(-60, 60, 41) * texel, np.linspace(-0.5, 0.5, 5) * texel)
    xy = through + s.reshape(-1, 1) * along + t.reshape(-1, 1) * across
    points = np.column_stack([xy, np.zeros(len(xy))])
    normals = np.tile([0.0, 0.0, 1.0], (len(points), 1))
    band, d = visibility.at_shadow_edge(shadow_map, window, points, normals,
                                        types.Light("SUN", direction=np.array([0.0, 0.0, -1.0])))
    assert (band > 0).all() and np.allclose(d[:, 2], 0.0) and np.allclose(np.linalg.norm(d, axis=1), 1.0)
    off = np.degrees(np.arccos(np.clip(np.abs(d[:, :2] @ along), 0.0, 1.0)))
    assert np.median(off) < 1.0 and off.max() < 2.5, np.percentile(off, [50, 90, 100])
