"""config.py: the JSON config -> (View, Light, SceneBounds, WarpOptions), with
every error naming its field (the CLI's malformed inputs are in test_cli.py)."""
import json
import math
from pathlib import Path

import numpy as np
import pytest

from addon.cli.config import ConfigError, parse_config
from addon.warp.geometry import ortho_matrix, perspective_matrix

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "examples").glob("*.json"))


def base():
    return json.loads((ROOT / "examples" / "outdoor_sun.json").read_text())


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_every_example_parses(path):
    view, light, scene, options = parse_config(json.loads(path.read_text()))
    assert len(scene.casters) >= 1 and options.shadow_map_size[0] >= 1


def test_perspective_camera_fields():
    c = base()
    view, light, scene, options = parse_config(c)
    cam = c["camera"]
    assert np.array_equal(view.camera_to_world, np.asarray(cam["matrix_world"], dtype=float))
    assert np.allclose(view.projection, perspective_matrix(math.radians(cam["fov_y_deg"]), cam["aspect"], cam["near"], cam["far"]))
    assert view.fov_y == pytest.approx(math.radians(cam["fov_y_deg"]))
    assert (view.near, view.far, view.resolution) == (cam["near"], cam["far"], tuple(cam["resolution"]))
    assert light.type == "SUN" and np.allclose(light.direction, np.array(c["light"]["direction"]) / np.linalg.norm(c["light"]["direction"]))
    assert len(scene.casters) == len(c["boxes"]) and options.shadow_map_size == (1024, 1024)


def test_aspect_defaults_to_the_resolution():
    c = base()
    del c["camera"]["aspect"]
    c["camera"]["resolution"] = [800, 400]
    view = parse_config(c)[0]
    assert view.projection[1, 1] / view.projection[0, 0] == pytest.approx(2.0)


def test_orthographic_camera():
    c = base()
    cam = c["camera"]
    del cam["fov_y_deg"]
    cam.update(orthographic=True, ortho_height=10.0, aspect=2.0)
    view = parse_config(c)[0]
    assert view.orthographic
    assert np.allclose(view.projection, ortho_matrix(-10, 10, -5, 5, cam["near"], cam["far"]))


def test_point_and_spot_lights():
    c = base()
    c["light"] = {"type": "POINT", "position": [1, 2, 3]}
    assert np.array_equal(parse_config(c)[1].position, [1, 2, 3])
    c["light"] = {"type": "SPOT", "position": [1, 2, 3], "direction": [0, 0, -2], "spot_angle_deg": 60}
    light = parse_config(c)[1]
    assert light.spot_angle == pytest.approx(math.radians(60)) and np.allclose(light.direction, [0, 0, -1])


def test_options_are_converted():
    c = base()
    c["shadow_map_size"] = [512, 256]
    c["planes"] = [{"point": [0, 0, 0], "normal": [0, 0, 2]}]
    c["options"] = {"texel_snapping": True, "delta_z": "visible", "visible_depth_range": [0.5, 40],
                    "middle_vector": True, "linear_z": True, "lam": 0.25, "max_frustum_angle": 100,
                    "plane_budget": 0.5, "plane_twist": "off"}
    o = parse_config(c)[3]
    assert o.shadow_map_size == (512, 256)
    assert o.texel_snapping and o.middle_vector and o.linear_z
    assert o.delta_z == "visible" and o.visible_depth_range == (0.5, 40.0)
    assert o.lam == 0.25 and o.max_frustum_angle == pytest.approx(math.radians(100))
    assert o.plane_budget == 0.5 and o.plane_twist == "off"
    (point, normal), = o.planes
    assert np.array_equal(point, [0, 0, 0]) and np.allclose(normal, [0, 0, 1])


def test_a_plane_extent_bounds_the_plane_map_as_planes_from_selection_does():
    """A plane's "extent" (the outline the sidebar's Planes From Selection keeps) reaches the warp: the plane map
    covers only that outline and leaves the rest of its texels to the fallback map."""
    from addon.warp import compute
    c = base()
    c["planes"] = [{"point": [0, 0, 0], "normal": [0, 0, 1]}]
    unbounded = compute("plane_optimal", *parse_config(c))
    c["planes"][0]["extent"] = [[-3, -3, 0], [3, -3, 0], [3, 3, 0], [-3, 3, 0]]
    table = compute("plane_optimal", *parse_config(c))
    assert np.allclose(np.ptp(table.maps[0].region.polygon, axis=0), [6, 6, 0])
    assert np.ptp(unbounded.maps[0].region.polygon, axis=0)[0] > 50
    plane_texels = [m.size[0] * m.size[1] for s in (table, unbounded) for m in s.maps if m.role == "plane:0"]
    assert plane_texels[0] < plane_texels[1] / 10


@pytest.mark.parametrize("extent", [[[-3, 0, 0], [0, 0, 0], [3, 0, 0]], [[1, 1, 0]] * 3,
                                    [[0, 0, 0], [0, 0, 4], [0, 0, -2]]], ids=["line", "point", "along_the_normal"])
def test_an_extent_with_no_area_on_its_plane_is_refused_by_field(extent):
    """Before, it was accepted and the plane then "has no visible part (behind the camera, outside the view, ...)"."""
    c = base()
    c["planes"] = [{"point": [0, 0, 0], "normal": [0, 0, 1], "extent": extent}]
    with pytest.raises(ConfigError, match=r"^planes\[0\]\.extent: the points lie on one line or point of the plane"):
        parse_config(c)


def test_null_optional_options():
    c = base()
    c["options"] = {"lam": None, "visible_depth_range": None}
    o = parse_config(c)[3]
    assert o.lam is None and o.visible_depth_range is None


@pytest.mark.parametrize("field,value", [("texel_snapping", None), ("delta_z", None), ("plane_budget", None)])
def test_required_options_are_not_null(field, value):
    c = base()
    c["options"] = {field: value}
    with pytest.raises(ConfigError, match=f"^options.{field}: "):
        parse_config(c)


def test_errors_start_with_the_field():
    c = base()
    c["boxes"][2]["max"] = [0, 0]
    with pytest.raises(ConfigError, match=r"^boxes\[2\]\.max: "):
        parse_config(c)
    c = base()
    c["light"]["direction"] = [0, 0, float("nan")]
    with pytest.raises(ConfigError, match=r"^light\.direction: "):
        parse_config(c)
