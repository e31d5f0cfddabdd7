"""The cascade's split search reads ``MAX_MAPS`` itself: a layout whose splits need more maps than the shading pass
reads scores inf in its sweeps and in its final check, so it never moves there and then falls back to the λ depths
(docs/papers.md, "splitcap, session 24")."""
import numpy as np
import pytest

from addon.warp import WarpOptions, compute
from addon.warp.methods.cascade import MAX_MAPS, Trials

from hard_cases import HARD_CASES


@pytest.mark.parametrize("splits", [2, 4])
def test_the_split_search_never_moves_to_a_layout_the_shading_pass_cannot_read(monkeypatch, splits):
    """point_light_inside_view: at 2 splits the search moved C_1 from Lloyd's layout of 7 maps (a cube and a focused
    map) to one of 9 (two cubes' faces), which the final check refused: the λ depths stayed and no layout within 8
    maps was tried from there; at 4 splits from 16 maps to 13. Every depth the search returns now needs at most
    ``MAX_MAPS`` maps, or is where it started."""
    found, search = [], Trials.searched_depths

    def recorded(self, start, warps):
        c = search(self, start, warps)
        found.append((np.array_equal(c, start), sum(len(s.setup.maps) for s in self.splits_at(c, warps, scored=False)
                                                     if s.setup is not None)))
        return c

    monkeypatch.setattr(Trials, "searched_depths", recorded)
    view, light, scene = HARD_CASES["point_light_inside_view"]
    setup = compute("cascade", view, light, scene, WarpOptions(shadow_map_size=1024, cascade_splits=splits))
    assert found and all(kept or needed <= MAX_MAPS for kept, needed in found), found
    assert len(setup.maps) <= MAX_MAPS
