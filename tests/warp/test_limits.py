"""Extreme but valid inputs to the warp core (issue: the CLI's limits): a right answer or a clear message, never an
out-of-memory kill. The coarse ray cast's memory stays bounded however many boxes each of its squares sees."""
import json
import tracemalloc
from pathlib import Path

import pytest

from addon.warp import region_from_boxes
from bench.visibility import cloud_seen_end_on


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
def test_a_box_far_larger_than_the_view_under_a_point_light_gets_a_message(light, half, tmp_path, capsys):
    """The core's tolerances and a point light's near floor are relative to the boxes meeting the view: a ground
    box ±1e11 wide puts the cube maps' near plane (1e-6 of it) beyond all the light shows in view, and no cube face
    is left. Every method on the whole B then says so, naming the light and what to do; it printed no maps with
    "cannot be computed (ValueError: need at least one array to concatenate)" or an internal IndexError. (cascade
    builds a B per split and gets maps.)"""
    config = json.loads(EXAMPLE.read_text())
    config["light"] = LIGHTS[light]
    config["boxes"] = config["boxes"][:37] + [{"min": [-half, -half, -2], "max": [half, half, -1]}]
    for method, result in run_all(config, tmp_path, capsys).items():
        error = result["diagnostics"].get("error", "")
        if method == "cascade":
            assert result["maps"] and not error, error
            continue
        assert not result["maps"] and error.startswith("Light 'light': the boxes in view span"), (method, error)
        assert "trim boxes far larger than the view" in error
