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
from addon.warp import WarpOptions, compute
from addon.warp.aliasing import raster_jacobian
from addon.warp.methods.cascade import Trials, single, stretched
from addon.warp.partition.receivers import (EDGES, LOSS, RAYS, filter_losses, footprint_p95, footprint_p95s, footprints,
                                          receivers)
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


def test_the_p95_of_each_union_at_once_is_the_p95_of_that_union():
    """``footprint_p95s`` (the cascade's descent scores every candidate of a split in one batch) gives, bit for bit,
    ``footprint_p95`` of the fixed splits' footprints joined with each candidate's: edge-on (inf) and unserved (NaN)
    left out, ties, a part or every part without a finite value; a candidate without one scores inf (the worst)."""
    rng = np.random.default_rng(5)
    for trial in range(300):
        def part(n):
            f = rng.lognormal(size=n) if trial % 3 else np.round(rng.lognormal(size=n), 1) + 0.1     # ties
            f[rng.random(n) < 0.05], f[rng.random(n) < 0.05] = np.inf, np.nan
            return f
        fixed = [part(int(rng.integers(0, 700 if trial % 2 else 3))) for _ in range(int(rng.integers(0, 4)))]
        choices = [part(int(rng.integers(0, 500 if trial % 5 else 3))) for _ in range(int(rng.integers(1, 20)))]
        expected = [footprint_p95(fixed + [c]) if np.isfinite(c).any() else np.inf for c in choices]
        assert footprint_p95s(fixed, choices).tolist() == expected


def test_footprints_in_one_batch_are_each_setups_own():
    """A map laid out anew (same matrix, another size) shares the raster Jacobian's matrix part with its original in
    ``footprints``' batch: each setup's footprints equal those it has alone."""
    view, light, scene = example("outdoor_sun")
    seen = receivers(view, light, region_from_boxes(view, scene), view.near, math.inf, scene)
    setup = compute("uniform", view, light, scene, WarpOptions(shadow_map_size=(1024, 1024), focus="view"))
    setups = [single(setup, size=s) for s in [(1024, 1024), *stretched((1024, 1024))]] + [setup]
    alone = [footprints([s], seen)[0] for s in setups]
    assert all(np.array_equal(a, b, equal_nan=True) for a, b in zip(footprints(setups, seen), alone))
    assert not np.allclose(alone[0], alone[1], equal_nan=True)


def edged(seen, points, directions):
    """``seen`` with shadow edges known at ``points`` on the ground (normal +z) running along ``directions`` (the
    engine's first look's)."""
    return (*seen[:4], np.stack([points, directions, np.broadcast_to([0.0, 0.0, 1.0], points.shape)], axis=1))


def sun_edges():
    """outdoor_sun's ``receivers``, its uniform map, ``EDGES`` + 5 of the receivers and ``along``: the direction on
    the ground whose image in that map runs along the given texel direction, at each of them."""
    view, light, scene = example("outdoor_sun")
    seen = receivers(view, light, region_from_boxes(view, scene), view.near, math.inf, scene)
    setup = compute("uniform", view, light, scene, WarpOptions(shadow_map_size=(1024, 1024), focus="view"))
    points = seen[0][::7][:EDGES + 5]
    jacobian = raster_jacobian(setup.maps[0].matrix, setup.maps[0].size, points[:1])[0]     # a sun's: the same anywhere

    def along(texels):
        d = np.append(np.linalg.solve(jacobian[:, :2], texels), 0.0)
        return np.broadcast_to(d / np.linalg.norm(d), points.shape)
    return seen, setup, points, along


def test_a_map_that_lays_the_known_shadow_edges_on_a_texel_axis_is_weighed_by_the_filter_gain_it_loses():
    """A grid along an edge holds nothing of the edge's place within a texel, so PCF 2's bilinear taps gain little
    there (docs/papers.md, the cascade's edges): where the shadow edges' directions are known, a single map whose
    texel axes lie along them counts its footprints 1 + ``LOSS`` times, one 45° off them once, and a map of several
    faces, or no edges, leaves its footprints as they are."""
    seen, setup, points, along = sun_edges()
    aligned, diagonal = (filter_losses([setup], edged(seen, points, along(t)))[0] for t in ([1.0, 0.0], [1.0, 1.0]))
    assert aligned == 1.0 + LOSS and diagonal == 1.0
    assert filter_losses([setup], edged(seen, points[:0], along([0.0, 1.0])[:0]))[0] == 1.0
    faces = dataclasses.replace(setup, maps=setup.maps * 2)
    assert filter_losses([faces, setup], edged(seen, points, along([0.0, 1.0]))).tolist() == [1.0, 1.0 + LOSS]


def test_a_splits_few_edge_samples_weigh_its_pick_in_proportion_to_how_many_there_are():
    """Fewer than ``EDGES`` edge samples are weighed, not dropped: their aligned share is shrunk toward the no-edge
    pick's 0 by n/``EDGES`` (as if the samples not seen were not aligned), so a split's loss grows with every sample
    that lies along a texel axis, is half the full one at ``EDGES``/2 and meets it at ``EDGES`` without a jump."""
    seen, setup, points, along = sun_edges()
    losses = [filter_losses([setup], edged(seen, points[:n], along([0.0, 1.0])[:n]))[0] for n in range(EDGES + 3)]
    assert losses[0] == 1.0 and np.all(np.diff(losses[:EDGES + 1]) > 0)
    assert math.isclose(losses[EDGES // 2], 1.0 + LOSS / 2, rel_tol=1e-12)
    assert losses[EDGES] == losses[EDGES + 2] == 1.0 + LOSS


def test_with_no_edges_known_the_candidates_are_scored_by_their_footprints_alone():
    """The CLI's region (the boxes' ray cast) knows no shadow edges: every candidate of a split, turned and laid out
    2:1, is scored by its footprints, bit for bit as before the edges were weighed (``tests.warp.golden``: no CLI
    setup moves)."""
    view, light, scene = example("outdoor_sun")
    region = region_from_boxes(view, scene)
    seen = receivers(view, light, region, view.near, math.inf, scene)
    assert seen[4].shape == (0, 3, 3)
    trials = Trials(view, light, scene, WarpOptions(shadow_map_size=1024, cascade_splits=2), region, seen)
    split = trials.splits_at(np.array([view.near, 20.0, view.far]))[0]
    scored = trials.candidates(split, split.far)
    depth = view.eye_depth(seen[0])
    mine = (*(x[(depth >= split.near) & (depth < split.far)] for x in seen[:4]), seen[4])
    assert len(scored) > 3 and all(np.array_equal(f, g, equal_nan=True) for (_, _, f), g in
                                   zip(scored, footprints([m for _, m, _ in scored], mine)))
