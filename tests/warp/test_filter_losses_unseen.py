"""``filter_losses`` weighs a candidate by the known shadow edges in front of its map only (docs/papers.md, "nanpick,
session 22"): a map that sees none of them, or a setup of several maps (a point light's cube faces), has nothing to
lose at them and keeps its footprints as they are (1), a finite weight and no "Mean of empty slice" warning. A NaN
weight made every footprint of that candidate NaN, so the cascade's p95s left its receivers out, as if it served
them for free."""
from __future__ import annotations

import dataclasses
import warnings

import numpy as np

from addon.warp.partition.receivers import EDGES, LOSS, filter_losses
from addon.warp.types import ShadowMap, ShadowSetup


def looking(sign: float) -> np.ndarray:
    """A 90° perspective map of a light at the origin looking along ``sign``·z (OpenGL NDC, near 0.1, far 100)."""
    n, f = 0.1, 100.0
    projection = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, -(f + n) / (f - n), -2 * f * n / (f - n)],
                           [0, 0, -1.0, 0]])
    return projection @ np.diag([1.0, sign * -1.0, sign * -1.0, 1.0])


def edges(z: float, count: int) -> tuple:
    """``count`` shadow edges on a plane z = ``z`` (normal +z), running along x: each map's texel axis there."""
    points = np.c_[np.linspace(-1.0, 1.0, count), np.linspace(-0.5, 0.5, count), np.full(count, z)]
    along = np.broadcast_to([1.0, 0.0, 0.0], points.shape)
    return np.stack([points, along, np.broadcast_to([0.0, 0.0, 1.0], points.shape)], axis=1)


def seen_with(samples: np.ndarray) -> tuple:
    return (np.zeros((0, 3)), np.zeros((0, 3)), None, None, samples)


def test_a_map_with_no_known_edge_in_front_of_it_or_several_maps_weigh_one_without_warnings():
    """Edges behind a map (w < 0) are none of its edges: a map that sees none is weighed 1, as with no edges known;
    so is a cube whose first face sees none (its faces: several maps); the map that sees them loses 1 + ``LOSS``."""
    ahead, behind = (ShadowSetup([ShadowMap(looking(s), (1024, 1024))], None) for s in (1.0, -1.0))
    cube = dataclasses.replace(behind, maps=behind.maps + ahead.maps)
    for count in (2, EDGES + 3):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            losses = filter_losses([behind, cube, ahead], seen_with(edges(5.0, count)))
        assert np.all(np.isfinite(losses)) and losses[:2].tolist() == [1.0, 1.0]
        assert losses[2] == 1.0 + LOSS * min(1.0, count / EDGES)


def test_edges_behind_a_map_count_neither_for_nor_against_it():
    """With ``EDGES`` edges in front of a map and as many behind it, its weight is that of the ones in front."""
    ahead = ShadowSetup([ShadowMap(looking(1.0), (1024, 1024))], None)
    front, back = edges(5.0, EDGES), edges(-5.0, EDGES)
    both = filter_losses([ahead], seen_with(np.concatenate([front, back])))
    assert both.tolist() == filter_losses([ahead], seen_with(front)).tolist() == [1.0 + LOSS]
