"""Which methods read the Visible Range (``methods.VISIBLE_RANGE_METHODS``, the core's fact that the panel and the
engine's check ask): where it says no, a Visible Range changes no map; where it says yes, it changes some map of some
example scene. (It lived in addon/scene, naming the core's methods from outside.)"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from addon.cli.config import parse_config
from addon.warp import WarpOptions, compute
from addon.warp.methods import METHODS, VISIBLE_RANGE_METHODS

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted(p.stem for p in (ROOT / "examples").glob("*.json"))


def setups(method: str, name: str):
    """``method``'s maps on example ``name`` without and with a Visible Range over the middle of the clip range."""
    view, light, scene, options = parse_config(json.loads((ROOT / "examples" / f"{name}.json").read_text()))
    options = dataclasses.replace(options, shadow_map_size=(512, 512), delta_z="visible")
    near, far = view.near, view.far
    ranged = dataclasses.replace(options, visible_depth_range=(near + 0.1 * (far - near), near + 0.3 * (far - near)))
    return [[(m.matrix, m.size, m.depth_row) for m in compute(method, view, light, scene, o).maps]
            for o in (options, ranged)]


def same(a, b) -> bool:
    return len(a) == len(b) and all(ma[1] == mb[1] and np.array_equal(ma[0], mb[0]) and
                                    (ma[2] is None) == (mb[2] is None) and (ma[2] is None or np.array_equal(ma[2], mb[2]))
                                    for ma, mb in zip(a, b))


@pytest.mark.parametrize("method", sorted(METHODS))
def test_only_the_methods_named_read_the_visible_range(method):
    changed = [name for name in EXAMPLES if not same(*setups(method, name))]
    assert bool(changed) == (method in VISIBLE_RANGE_METHODS), changed
