"""Extreme but valid inputs to the warp core (issue: the CLI's limits): a right answer or a clear message, never an
out-of-memory kill. The coarse ray cast's memory stays bounded however many boxes each of its squares sees."""
import json
import math
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from addon.warp import METHODS, compute, focused_body, region_from_boxes
from bench.visibility import cloud_seen_end_on
from hard_cases import _street, huge_ground, point, spot, sun


def peak_bytes(view, scene) -> tuple[int, object]:
    tracemalloc.start()
    try:
        region = region_from_boxes(view, scene)
        return tracemalloc.get_traced_memory()[1], region
    finally:
        tracemalloc.stop()


def test_the_coarse_ray_cast_takes_bounded_memory_however_many_boxes_a_square_sees():
    """3,000 deep boxes over the whole image (~2M (square, box) pairs) peaked at 1.3 GB (tracemalloc) when every pair
    was held at once; taken in chunks the peak stays under 100 MB and about that of 750 boxes."""
    big, region = peak_bytes(*cloud_seen_end_on(3000))
    small, _ = peak_bytes(*cloud_seen_end_on(750))
    assert not region.is_empty
    assert big < 100e6, f"{big / 1e6:.0f} MB"
    assert big < 2 * small + 20e6, (big / 1e6, small / 1e6)


EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "outdoor_sun.json"
LIGHTS = {"sun": {"type": "SUN", "direction": [0.3, 0.2, -1]}, "point": {"type": "POINT", "position": [3, 2, 20]},
          "spot": {"type": "SPOT", "position": [3, 2, 20], "direction": [0, 0, -1], "spot_angle_deg": 120}}


def run_all(config, tmp_path, capsys) -> dict:
    """``python -m addon.warp --method all`` in-process: {method: its JSON}."""
    from addon.cli import main
    path = tmp_path / "config.json"
    path.write_text(json.dumps(config))
    code, out = main(["--method", "all", str(path)]), capsys.readouterr()
    assert code == 0 and "Traceback" not in out.err, out.err
    return json.loads(out.out)["methods"]


@pytest.mark.parametrize("light", list(LIGHTS))
def test_a_box_far_from_the_view_changes_no_map(light, tmp_path, capsys):
    """float64 has the range: a box 1e8 or 1e11 away (within MAX_COORDINATE) meets neither the view nor the light's
    reach into it, so every method's maps are exactly those without it."""
    config = json.loads(EXAMPLE.read_text())
    config["light"] = LIGHTS[light]
    alone = run_all(config, tmp_path, capsys)
    for far in (1e8, 1e11):
        config["boxes"] = config["boxes"][:37] + [{"min": [far, far, 0], "max": [far + 1, far + 1, 1]}]
        with_it = run_all(config, tmp_path, capsys)
        for method, result in alone.items():
            assert result["maps"], (method, result["diagnostics"])
            assert with_it[method]["maps"] == result["maps"], (method, far)


@pytest.mark.parametrize("light,half", [("point", 1e11), ("point", 1e12), ("spot", 1e12)])
def test_a_huge_box_under_a_point_light_gives_the_maps_of_its_trimmed_twin(light, half, tmp_path, capsys):
    """B's scale (its tolerances, a point light's near floor) comes from what the view can see: a ground box ±1e11
    or ±1e12 wide under the example's ground gives every method (the CLI's JSON) the maps of the same box trimmed to
    ±1e3. (From the boxes meeting the view, the cube maps' near plane lay beyond all the light shows in view: only
    cascade got maps, the others "trim boxes far larger than the view".)"""
    config = json.loads(EXAMPLE.read_text())
    config["light"] = LIGHTS[light]
    config["boxes"] = config["boxes"][:37] + [{"min": [-1e3, -1e3, -2], "max": [1e3, 1e3, -1]}]
    twin = run_all(config, tmp_path, capsys)
    config["boxes"][37] = {"min": [-half, -half, -2], "max": [half, half, -1]}
    for method, result in run_all(config, tmp_path, capsys).items():
        assert result["maps"] and result["maps"] == twin[method]["maps"], (method, result["diagnostics"])


HUGE_GROUND_LIGHTS = {"sun": sun([0.4, 0.3, -0.6]), "sun 1° high": sun([0.3, 1.0, -math.tan(math.radians(1.0)) * math.hypot(0.3, 1.0)]),
                      "spot": spot([-10.0, -10.0, 25.0], [0.4, 0.6, -1.0], math.radians(70.0)),
                      "point above": point([0.0, 10.0, 60.0]), "point in view": point([0.0, 8.0, 2.0])}


@pytest.mark.parametrize("light", list(HUGE_GROUND_LIGHTS))
def test_a_ground_of_any_size_gives_the_maps_of_its_trimmed_twin(light):
    """A ground modelled as one huge box, ±1e4 to ±1e12 m (an 'endless' floor), gives every method exactly the maps
    of the same ground trimmed to what the view can see and what can shadow it (``hard_cases.huge_ground``). B's
    scale came from the boxes meeting the view: over ±1e7 m a sun's maps moved 10-100 % of their largest entry, a
    spot's over ±1e8 by 1e14; a point light in view got "cannot be computed (ZeroDivisionError)" from ±1e6 on, a spot
    over ±1e11 "the view frustum does not meet the receivers"."""
    view, lamp = _street(), HUGE_GROUND_LIGHTS[light]

    def maps(scene) -> dict:
        body = focused_body(view, lamp, scene)
        return {m: [s.matrix for s in compute(m, view, lamp, scene, body=body).maps] for m in METHODS}

    twin = maps(huge_ground(view, None))
    for half in (1e4, 1e8, 1e12):
        for method, got in maps(huge_ground(view, half)).items():
            assert len(got) == len(twin[method]) and all(map(np.array_equal, got, twin[method])), (method, half)
