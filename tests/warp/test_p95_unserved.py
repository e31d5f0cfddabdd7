"""A cascade candidate whose footprints hold no finite value (every receiver of its split edge-on to it, unserved by
its maps, or NaN) serves none of them: its p95 is the worst, inf, so neither the descent over a split's candidates
(``footprint_p95s``) nor a split's least (``Trials.least``) picks it over one that serves them (docs/papers.md,
"p95inf, session 23"). A p95 of 0 made it the best of all: its receivers dropped out of the cascade's p95s."""
from __future__ import annotations

import types

import numpy as np

from addon.warp.methods.cascade import Trials
from addon.warp.partition.receivers import TAIL, footprint_p95, footprint_p95s

RNG = np.random.default_rng(23)
SERVED = RNG.lognormal(1.0, 0.5, 400)
UNSERVED = [np.full(400, np.inf), np.full(400, np.nan), np.where(RNG.random(400) < 0.5, np.inf, np.nan), np.zeros(0)]


def test_a_candidate_without_a_finite_footprint_scores_the_worst_p95():
    """Alone or beside the other splits' footprints, each unserved candidate scores inf and the served one least."""
    for fixed in ([], [RNG.lognormal(size=300)], [RNG.lognormal(size=300), np.full(5, np.nan)]):
        scores = footprint_p95s(fixed, [*UNSERVED, SERVED * 40.0])
        assert scores[:-1].tolist() == [np.inf] * len(UNSERVED) and np.isfinite(scores[-1])
        assert int(np.argmin(scores)) == len(UNSERVED)


def test_footprints_with_no_finite_value_have_the_worst_p95():
    """A layout of splits that serve none of their receivers is never the better one (the split search's tail)."""
    for band in ((95.0,), TAIL):
        assert footprint_p95(UNSERVED, band) == np.inf
        assert footprint_p95([*UNSERVED, SERVED], band) == footprint_p95([SERVED], band) < np.inf


def test_a_splits_least_is_a_candidate_that_serves_its_receivers():
    """``Trials.least`` of a split whose first candidates serve none of its receivers is the one that does."""
    trials = Trials(view=None, light=None, scene=None, options=None)
    trials.candidates = lambda split, far, laid=True: [("psm", None, f) for f in (*UNSERVED, SERVED)]
    least = trials.least(types.SimpleNamespace(near=1.0, warp="psm"), 10.0)
    assert least is SERVED
