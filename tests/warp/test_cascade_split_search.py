"""The cascade's split search (``Trials.searched_depths``; docs/papers.md, "p95inf, session 23"): a layout whose maps
exceed ``MAX_MAPS`` is never kept (the cascade could not draw it: it then fell back to the λ depths), and where two
layouts' p95s over all receivers tie within ``MARGIN`` the one whose worst split is lower wins (Lloyd's minimax view):
gen1_05_point_low_in_view's far receivers, given their own map, err 0.4x as often as in the light's cube."""
from __future__ import annotations

import types

import numpy as np

from addon.warp.methods.cascade import MARGIN, MAX_MAPS, TAIL, Trials, tied, worst
from addon.warp.partition.receivers import footprint_p95

NEAR = np.linspace(1.0, 10.0, 1000)            # the near split's footprints: they set the p95 over all receivers
START = (MAX_MAPS, [NEAR, np.linspace(5.0, 30.0, 20)])


def searched(layouts: dict) -> float:
    """The inner depth ``searched_depths`` keeps from (1, 2, 4) (orthographic: trials at 1.6, 2.2, 2.8 and 3.4), each
    layout's maps and per-split footprints ``layouts[depth]`` (the start's and any other: ``START``)."""
    trials = Trials(view=types.SimpleNamespace(orthographic=True), light=None, scene=None, options=None)
    at = {}

    def splits_at(c, warps, scored=True):
        maps, footprints = layouts.get(round(float(c[1]), 3), START)
        splits = [types.SimpleNamespace(setup=types.SimpleNamespace(maps=[None] * (maps // 2 + k * (maps % 2))))
                  for k in range(2)]
        at.update({id(s): f for s, f in zip(splits, footprints)})
        return splits
    trials.splits_at, trials.least = splits_at, lambda split, far: at[id(split)]
    return float(trials.searched_depths(np.array([1.0, 2.0, 4.0]), ["uniform"] * 2)[1])


def test_a_layout_of_more_maps_than_the_shading_pass_reads_is_never_kept():
    """A layout of ``MAX_MAPS`` + 1 maps with half the p95 is passed over; one of ``MAX_MAPS`` is taken."""
    better = [NEAR / 2.0, np.linspace(2.0, 15.0, 20)]
    assert searched({1.6: (MAX_MAPS + 1, better)}) == 2.0
    assert searched({1.6: (MAX_MAPS, better)}) == 1.6


def test_a_tie_of_the_p95s_goes_to_the_layout_whose_worst_split_is_lower():
    """The same p95 over all receivers (within ``MARGIN``), the far split's a third lower: taken; not lower: not."""
    far = [NEAR, np.linspace(5.0, 20.0, 20)]
    a, b = ((footprint_p95(f, TAIL), worst(f)) for f in (far, START[1]))
    assert abs(a[0] / b[0] - 1.0) < MARGIN and a[1] < 0.7 * b[1] and tied(a, b) and not tied(b, a)
    assert searched({2.8: (MAX_MAPS, far)}) == 2.8
    assert searched({2.8: (MAX_MAPS, [NEAR, np.linspace(5.0, 29.5, 20)])}) == 2.0
