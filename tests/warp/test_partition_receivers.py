"""The receivers' sample (docs/papers.md, "The receivers' footprint"): where the visible region is the scene boxes'
ray cast, the cascade scores its maps at the hits of a finer cast through ``RAYS``, each with its face's normal; any
other region's samples are its own."""
from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from addon.cli.config import parse_config
from addon.measure.box_scene import visible_points
from addon.warp.partition.receivers import RAYS, receivers
from addon.warp.visibility import BOX_SAMPLES, region_from_boxes

ROOT = Path(__file__).resolve().parents[2]


def example(name):
    view, light, scene, _ = parse_config(json.loads((ROOT / "examples" / f"{name}.json").read_text()))
    return view, light, scene


def test_where_the_region_is_the_boxes_ray_cast_the_receivers_are_the_hits_of_a_finer_cast():
    """Each receiver is a hit of the judge's own ray cast through the centres of the ``RAYS`` grid, with its face's
    normal: more of the visible surface than the region's own samples."""
    view, light, scene = example("outdoor_sun")
    region = region_from_boxes(view, scene)
    seen = receivers(view, light, region, view.near, math.inf, scene)
    points, normals = visible_points(view, scene, RAYS)
    assert np.prod(RAYS) > 1.5 * np.prod(BOX_SAMPLES)
    assert len(seen[0]) == len(points) > 1.5 * len(region.normals)
    assert np.allclose(seen[0], points, atol=1e-6 * float(np.ptp(points)))
    assert np.allclose(np.abs(seen[1]), np.abs(normals))


def test_any_other_region_gives_its_own_samples_and_none_without_normals():
    """A region from elsewhere (the engine's pre-pass) is sampled as it is; one without normals gives no receivers,
    as the cascade then has Lloyd's model alone."""
    view, light, scene = example("outdoor_sun")
    region = dataclasses.replace(region_from_boxes(view, scene), source="depth pre-pass")
    seen = receivers(view, light, region, view.near, math.inf, scene)
    assert np.array_equal(seen[0], region.surface[:, 0]) and np.array_equal(seen[1], region.normals)
    assert receivers(view, light, dataclasses.replace(region_from_boxes(view, scene), normals=None), view.near,
                     math.inf, scene) is None
