"""Every method covers what the view needs, judged without trusting B.

The judge (addon.measure.box_scene) ray-casts visible points from camera pixels
and walks their shadow rays through the caster boxes: every visible point must
be served by a map, every caster on its shadow ray must be in that same map, and
the caster must win the map's depth test. This is the outside evaluation's
coverage rule, on the bundled examples and on every named hard case.
"""
import glob
import json
from pathlib import Path

import numpy as np
import pytest

from addon.measure.box_scene import caster_points, judge, visible_points
from addon.warp import METHODS, WarpOptions, compute
from addon.cli.config import parse_config
from hard_cases import EMPTY_CASES, HARD_CASES, sun, camera, town

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = {Path(p).stem: p for p in sorted(glob.glob(str(ROOT / "examples" / "*.json")))}
CASES = [name for name in HARD_CASES if name not in EMPTY_CASES]


def _example(name):
    view, light, scene, _ = parse_config(json.loads(Path(EXAMPLES[name]).read_text()))
    return view, light, scene


@pytest.mark.parametrize("method", list(METHODS))
@pytest.mark.parametrize("example", list(EXAMPLES))
def test_every_visible_point_and_its_casters_are_covered_on_the_examples(method, example):
    view, light, scene = _example(example)
    j = judge(view, light, scene, compute(method, view, light, scene, WarpOptions(shadow_map_size=1024)),
              samples=(64, 36))
    assert j.visible > 100
    assert (j.uncovered, j.casters_uncovered, j.depth_order_wrong) == (0, 0, 0)


@pytest.mark.parametrize("method", list(METHODS))
@pytest.mark.parametrize("case", CASES)
def test_every_visible_point_and_its_casters_are_covered_on_hard_cases(method, case):
    view, light, scene = HARD_CASES[case]
    j = judge(view, light, scene, compute(method, view, light, scene, WarpOptions(shadow_map_size=1024)),
              samples=(48, 27))
    assert (j.uncovered, j.casters_uncovered, j.depth_order_wrong) == (0, 0, 0)
    assert np.isfinite(j.footprint_p95)


def test_the_judge_sees_visible_points_and_casters():
    view = camera([0.0, -10.0, 2.0], [0.0, 5.0, 0.0])
    scene = town()
    pts, normals = visible_points(view, scene, (32, 18))
    assert len(pts) > 300 and np.allclose(np.linalg.norm(normals, axis=1), 1.0)
    cpts, owner = caster_points(pts, sun([0.4, 0.3, -0.6]), scene)
    assert len(cpts) > 0 and owner.max() < len(pts)


def test_the_judge_fails_a_map_that_misses_casters():
    """A map fitted to the visible points only must fail once a caster floats out of view
    between the ground and the sun."""
    from addon.warp.fit import fit_to_unit_cube
    from addon.warp.frame import sun_frame
    from addon.warp import intersection_body
    from addon.warp.types import ShadowMap, ShadowSetup, Diagnostics
    view = camera([0.0, -10.0, 2.0], [0.0, 5.0, 0.0])
    light = sun([0.4, 0.3, -0.6])
    base = town()
    floating = np.array([[[-9.0, -2.0, 11.5], [-7.0, 0.0, 12.5]]])   # above the view, toward the sun
    scene = type(base).from_boxes(np.concatenate([base.casters, floating]))
    assert len(visible_points(view, type(base).from_boxes(floating), (48, 27))[0]) == 0
    body = intersection_body(view, light, scene)
    frame = sun_frame(view, light, body)
    pts, _ = visible_points(view, scene, (48, 27))
    too_tight = ShadowSetup([ShadowMap(fit_to_unit_cube(frame.to_light, pts), (64, 64))], Diagnostics("tight"))
    j = judge(view, light, scene, too_tight, samples=(48, 27))
    assert j.casters_uncovered > 0
