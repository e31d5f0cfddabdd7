"""What the cascade keeps between the steps of one change of view (``Trials``: each split's B, maps, turns and its
receivers' candidates, kept by the split's depths, so that Lloyd's rounds, the split search and the second pick do
not make them again) is bit for bit what those steps would make afresh, and nothing is kept from one view to the
next (docs/performance.md, the cascade's CPU per change of view)."""
from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np

from addon.cli.config import parse_config
from addon.warp import WarpOptions, compute
from addon.warp.methods.cascade import Trials
from addon.warp.partition.receivers import entries, receivers
from addon.warp.partition.splits import practical_splits
from addon.warp.visibility import region_from_boxes

ROOT = Path(__file__).resolve().parents[2]
OPTIONS = WarpOptions(shadow_map_size=1024, cascade_splits=3)


def example(name):
    view, light, scene, _ = parse_config(json.loads((ROOT / "examples" / f"{name}.json").read_text()))
    return view, light, scene


def picked(trials: Trials, depths) -> tuple[list, list]:
    """(warp, matrices, sizes) of each split ``least_footprint`` picks between ``depths``, and its footprints."""
    splits, seen = trials.least_footprint(trials.splits_at(np.asarray(depths, dtype=np.float64)))
    return [(s.warp, [m.matrix for m in s.setup.maps], [m.size for m in s.setup.maps]) for s in splits], seen


def same(a, b) -> bool:
    """Equal bit for bit (NaN where NaN), through nested lists and tuples of arrays."""
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return np.array_equal(a, b, equal_nan=True) if isinstance(a, np.ndarray) else a == b


def test_the_second_pick_reuses_only_the_splits_whose_depths_it_meets_again():
    """The split search's pick at its new depths (the first split's far end moved, the last split as before) gives
    what a fresh ``Trials`` gives there, and made the unmoved split's candidates once."""
    view, light, scene = example("outdoor_sun")
    region = region_from_boxes(view, scene)
    seen = receivers(view, light, region, view.near, math.inf, scene)
    z_n, z_f = region.depth_range
    start = practical_splits(z_n, z_f, 3, 0.5)
    moved = start.copy()
    moved[1] = start[0] * (start[2] / start[0]) ** 0.3
    trials = Trials(view, light, scene, OPTIONS, region, seen)
    picked(trials, start)
    again = picked(trials, moved)
    assert same(again, picked(Trials(view, light, scene, OPTIONS, region, seen), moved))
    assert not same(again[1][0], picked(Trials(view, light, scene, OPTIONS, region, seen), start)[1][0])
    assert sum(key[0] == "candidates" for key in trials.made) == 5        # 3 + the 2 splits whose depths moved


def moved_case():
    """outdoor_sun's camera turned 2° about the world's z through its eye, its visible depths held to a range
    inside what it sees (so the λ splits, and the keys of what ``Trials`` keeps, are those of the view before)."""
    view, light, scene = example("outdoor_sun")
    z_n, z_f = region_from_boxes(view, scene).depth_range
    options = dataclasses.replace(OPTIONS, visible_depth_range=(1.5 * z_n, 0.7 * z_f))
    a = math.radians(2.0)
    turn = np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]])
    m = view.camera_to_world.copy()
    m[:3, :3] = turn @ m[:3, :3]
    return view, dataclasses.replace(view, camera_to_world=m), light, scene, options


def digest(setup) -> str:
    return hashlib.sha1(b"".join(m.matrix.tobytes() + repr(tuple(m.size)).encode() for m in setup.maps)).hexdigest()


def test_a_moved_view_gets_the_cascade_it_gets_alone():
    """The cascade of a view computed just after the view before it equals, bit for bit, the one a fresh process
    computes for it alone: nothing the view before made (its splits' B, maps, candidates) is served to it."""
    view, moved, light, scene, options = moved_case()
    before = compute("cascade", view, light, scene, options)
    after = compute("cascade", moved, light, scene, options)
    ends = [[s.diagnostics.extra["splits"][k] for k in (0, -1)] for s in (before, after)]
    assert ends[0] == ends[1]                     # the same z_n, z_f: the same λ splits, the keys of what is kept
    alone = subprocess.run([sys.executable, "-c", "from tests.warp.test_cascade_reuse import *; "
                            "_, moved, light, scene, options = moved_case(); "
                            "print(digest(compute('cascade', moved, light, scene, options)))"],
                           cwd=ROOT, capture_output=True, text=True, check=True).stdout.split()[-1]
    assert digest(after) == alone != digest(before)


def test_the_entries_of_2x2_matrices_are_added_in_numpys_order():
    """``entries`` (the footprints' Frobenius norms and largest entries) adds as ``sum(axis=(-2, -1))`` does, bit for
    bit, over values of every magnitude and sign, and takes the largest as ``max`` does (NaN kept)."""
    rng = np.random.default_rng(3)
    a = rng.standard_normal((200, 500, 2, 2)) * np.exp(6.0 * rng.standard_normal((200, 500, 2, 2)))
    a[0, :4] = np.nan
    assert np.array_equal(entries(a, np.add), a.sum(axis=(-2, -1)), equal_nan=True)
    assert np.array_equal(entries(np.abs(a), np.maximum), np.max(np.abs(a), axis=(-2, -1)), equal_nan=True)
