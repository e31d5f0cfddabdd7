"""Maps that differ by a map of x/w, y/w share one raster Jacobian (``partition.receivers.jacobians``): PSM's turns
(``methods.psm.TURNS``) and the cascade's ``turned`` maps keep their first's z and w rows, so d(x/w, y/w) of each is
a 2x2 matrix times the first's, at every point; their Jacobians are each one's own, to rounding."""
import numpy as np
import pytest

from addon.warp import compute
from addon.warp.aliasing import raster_jacobian
from addon.warp.fit import fit_to_unit_cube
from addon.warp.geometry import translation
from addon.warp.methods.warp_frustum import TURNS
from addon.warp.partition import receivers
from addon.warp.types import ShadowMap

from test_psm_edge_axes import low_sun_with_lit_points


def psm_turns_and_lit_points():
    """gen46_08_low_sun's PSM map turned by each of ``TURNS`` and fitted again as ``turned_fit`` does, 1024² and one
    2896 x 1448, and the fixture's lit points (the receivers) with their tangent bases."""
    view, light, scene, options, body, points, normals = low_sun_with_lit_points()
    relative = compute("psm", view, light, scene, options, body=body).maps[0].matrix @ translation(view.position)
    turns = fit_to_unit_cube(TURNS @ relative, body.vertices - view.position) @ translation(-view.position)
    maps = [ShadowMap(m, (1024, 1024)) for m in turns] + [ShadowMap(turns[5], (2896, 1448))]
    tangent = np.stack([np.cross(normals, [0.0, 0.0, 1.0]), np.cross(normals, [1.0, 0.0, 0.0])], 2)
    return maps, points, tangent


def alone(m: ShadowMap, points: np.ndarray) -> np.ndarray:
    """Its ``raster_jacobian`` by itself."""
    return raster_jacobian(m.matrix, m.size, points)


def test_psms_turns_get_each_ones_own_jacobian_from_one_raster_jacobian(monkeypatch):
    maps, points, tangent = psm_turns_and_lit_points()
    calls = []
    monkeypatch.setattr(receivers, "raster_jacobian", lambda m, *a: calls.append(len(m)) or raster_jacobian(m, *a))
    together, images = receivers.jacobians(maps, points), receivers.jacobians(maps, points, tangent)
    assert calls == [1, 1]                                # 37 maps, one matrix of d(x/w, y/w) per call
    for m, d, h in zip(maps, together, images):
        scale = np.abs(alone(m, points)).max(axis=(1, 2))[:, None, None]
        np.testing.assert_array_less(np.abs(d - alone(m, points)) / scale, 1e-9)
        np.testing.assert_array_less(np.abs(h - alone(m, points) @ tangent) / scale, 1e-9)


def test_the_cascades_turned_maps_share_their_z_and_w_rows():
    """``partition.receivers.turned`` turns a map to its points' image hull and fits it again: z, w rows alike."""
    maps, points, _ = psm_turns_and_lit_points()
    hull = receivers.turned(maps[0].matrix, points)
    assert len(hull) > 1 and all(np.array_equal(t[2:], hull[0][2:]) for t in hull)
    d = receivers.jacobians([ShadowMap(t, (2048, 2048)) for t in hull], points)
    for t, got in zip(hull, d):
        want = raster_jacobian(t, (2048, 2048), points)
        np.testing.assert_array_less(np.abs(got - want) / np.abs(want).max(axis=(1, 2))[:, None, None], 1e-9)


@pytest.mark.parametrize("mixed", [0.5, 1e-6])
def test_maps_with_the_same_z_and_w_rows_but_not_a_map_of_x_w_y_w_are_their_own(mixed):
    """x rows with some of the z row in them: d(x/w) then holds d(z/w), which no 2x2 of d(x/w, y/w) gives."""
    maps, points, _ = psm_turns_and_lit_points()
    other = maps[0].matrix.copy()
    other[0] += mixed * np.abs(other[0]).max() / np.abs(other[2]).max() * other[2]
    d = receivers.jacobians([maps[0], ShadowMap(other, maps[0].size)], points)
    np.testing.assert_allclose(d[1], alone(ShadowMap(other, maps[0].size), points), rtol=1e-12, atol=0)
    np.testing.assert_allclose(d[0], alone(maps[0], points), rtol=1e-12, atol=0)
