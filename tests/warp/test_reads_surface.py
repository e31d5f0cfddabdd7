"""Which methods read the seen surface (``methods.reads_surface``, issue 15's wasted work): the engine reads the camera
pre-pass back whole (``VisibleRegion.surface`` and ``normals``, about 4 ms at 1280x720) only for them, so where it
says no the surface changes no map, and where it says yes the maps are those computed with the surface."""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from addon.cli.config import parse_config
from addon.warp import WarpOptions, compute
from addon.warp.methods import METHODS, reads_surface
from addon.warp.visibility import region_from_boxes

ROOT = Path(__file__).resolve().parents[2]
BASE = WarpOptions(shadow_map_size=512)
SURFACE_BLIND = {
    "stable cascade": ("cascade", dict(cascade_stable=True)),
    "one-split cascade": ("cascade", dict(cascade_splits=1)),
    "practical cascade": ("cascade", dict(cascade_adaptive=False)),
    "plane_optimal, planes given": ("plane_optimal", dict(planes=(((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)),))),
    **{name: (name, {}) for name in METHODS if name not in ("cascade", "plane_optimal")},
}
"""Configurations that read no surface."""
SURFACE_READERS = {"adaptive cascade": ("cascade", {}), "plane_optimal, default plane": ("plane_optimal", {})}


def scene_of(name: str):
    view, light, scene, _ = parse_config(json.loads((ROOT / "examples" / f"{name}.json").read_text()))
    return view, light, scene


def matrices(setup) -> list:
    return [(m.role, m.size, m.matrix, m.view_depth_range, m.depth_row) for m in setup.maps]


def same_maps(a, b) -> bool:
    """Whether two setups have the same maps, bit for bit."""
    a, b = matrices(a), matrices(b)
    return len(a) == len(b) and all(
        x[:2] == y[:2] and np.array_equal(x[2], y[2]) and x[3] == y[3]
        and (x[4] is None if y[4] is None else np.array_equal(x[4], y[4])) for x, y in zip(a, b))


def test_the_default_cascade_and_plane_optimal_read_the_surface_the_other_configurations_do_not():
    for what, (method, fields) in SURFACE_READERS.items():
        assert reads_surface(method, dataclasses.replace(BASE, **fields)), what
    for what, (method, fields) in SURFACE_BLIND.items():
        assert not reads_surface(method, dataclasses.replace(BASE, **fields)), what


@pytest.mark.parametrize("example", ["outdoor_sun", "chess_spot"])
@pytest.mark.parametrize("what", list(SURFACE_BLIND))
def test_where_no_surface_is_read_it_changes_no_map(example, what):
    """The same visible region with and without its surface samples gives the same maps, bit for bit."""
    method, fields = SURFACE_BLIND[what]
    view, light, scene = scene_of(example)
    options = dataclasses.replace(BASE, **fields)
    region = region_from_boxes(view, scene)
    assert region.surface is not None and region.normals is not None
    blind = dataclasses.replace(region, surface=None, normals=None)
    assert same_maps(compute(method, view, light, scene, options, visible=region),
                     compute(method, view, light, scene, options, visible=blind))


def test_the_adaptive_cascade_does_read_it():
    """Its splits' maps are scored at the seen receivers: on the outdoor sun without them it picks other maps."""
    view, light, scene = scene_of("outdoor_sun")
    region = region_from_boxes(view, scene)
    blind = dataclasses.replace(region, surface=None, normals=None)
    assert not same_maps(compute("cascade", view, light, scene, BASE, visible=region),
                         compute("cascade", view, light, scene, BASE, visible=blind))
