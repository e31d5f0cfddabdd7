"""LiSPSM, GMNPR and GLPR turn their texel axes off the shadow edges as PSM does (``warp_frustum.edge_turned``;
docs/papers.md, "Texel axes off the shadow edges")."""
import dataclasses

import numpy as np
import pytest

from addon.warp import compute
from addon.warp.aliasing import raster_jacobian

from test_psm_edge_axes import grid_angles, low_sun_with_lit_points


@pytest.mark.parametrize("method", ["lispsm", "gmnpr", "glpr"])
def test_the_lispsm_family_turns_its_texel_axes_off_the_shadow_edges_it_is_given(method):
    """Their x, y are the light frame's lateral axis and V_P (``warp_matrix``), set without the edges: given the first
    look's edge samples lying along its x axis on the lit receivers, the one map turns about its depth axis so that
    they lie 20-45° off both axes, B still inside."""
    view, light, scene, options, body, points, normals = low_sun_with_lit_points()
    plain = compute(method, view, light, scene, options, body=body).maps[0].matrix
    j = raster_jacobian(plain, (2, 2), points)
    d = np.linalg.solve(np.stack([j[:, 0], j[:, 1], normals], 1), np.tile([1.0, 0.0, 0.0], (len(points), 1)))
    d /= np.linalg.norm(d, axis=1)[:, None]                                      # D_M·d = (·, 0), n·d = 0
    assert np.median(grid_angles(plain, points, d)) < 0.01
    looked = dataclasses.replace(body, visible=dataclasses.replace(
        body.visible, surface=np.stack([points, points], 1), normals=normals, edge_directions=d))
    setup = compute(method, view, light, scene, options, body=looked)
    assert setup.maps[0].contains(body.vertices, 1e-6).all()
    assert np.percentile(grid_angles(setup.maps[0].matrix, points, d), 10) >= 20.0
