"""``python -m addon.warp``: the JSON it prints, one-line errors for malformed
configs (never a traceback), empty bodies reported, and no bpy anywhere.

Run with plain ``python3`` (numpy only) in a subprocess, as a user would."""
import copy
import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "examples").glob("*.json"))


def _plain_python() -> str:
    """Plain ``python3`` when it has numpy (as a user runs the CLI), else this
    interpreter (a Blender venv: bpy is installed there, but the core must not
    import it, which the tests check through ``sys.modules``)."""
    exe = shutil.which("python3")
    if exe and subprocess.run([exe, "-c", "import numpy"], capture_output=True).returncode == 0:
        return exe
    return sys.executable


PLAIN_PYTHON = _plain_python()


def run_cli(*args, stdin=None, python=None):
    env = dict(os.environ)
    env.pop("LIXEL_DEBUG", None)
    env["PYTHONPATH"] = str(ROOT)
    return subprocess.run([python or PLAIN_PYTHON, "-m", "addon.warp", *args], input=stdin, capture_output=True,
                          text=True, cwd=ROOT, env=env, timeout=120)


def base_config():
    return json.loads((ROOT / "examples" / "outdoor_sun.json").read_text())


def methods():
    from addon.warp import METHODS
    return list(METHODS)


def check_setup_json(obj):
    assert set(obj) == {"maps", "diagnostics"}
    for m in obj["maps"]:
        mat = np.asarray(m["matrix"], dtype=float)
        assert mat.shape == (4, 4) and np.all(np.isfinite(mat))
        assert len(m["size"]) == 2 and all(isinstance(v, int) and v >= 1 for v in m["size"])
        assert m["depth_test"] in ("LESS", "GREATER")
        assert isinstance(m["role"], str)
        if "view_depth_range" in m:
            a, b = m["view_depth_range"]
            assert a <= b
    d = obj["diagnostics"]
    assert "method" in d and isinstance(d["fallbacks"], list)


# ----------------------------------------------------------------------------- the happy path

@pytest.mark.parametrize("module", ["addon", "addon.warp", "addon.warp.__main__", "addon.cli", "addon.cli.config"])
def test_importing_the_core_does_not_import_bpy(module):
    r = subprocess.run([PLAIN_PYTHON, "-c", f"import {module}, sys; assert 'bpy' not in sys.modules, 'bpy imported'"],
                       capture_output=True, text=True, cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert r.returncode == 0, r.stderr


@pytest.mark.parametrize("example", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_all_methods_on_every_example(example):
    r = run_cli("--method", "all", str(example))
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert list(out) == ["methods"] and list(out["methods"]) == methods()
    for name, obj in out["methods"].items():
        check_setup_json(obj)
        assert obj["diagnostics"]["method"] == name
        assert "error" not in obj["diagnostics"], obj["diagnostics"]["error"]
        assert obj["maps"], f"{name}: no maps"


def test_single_method_matches_compute():
    from addon.warp import compute
    from addon.cli.config import parse_config
    config = base_config()
    r = run_cli("--method", "uniform", "-", stdin=json.dumps(config))
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    check_setup_json(out)
    view, light, scene, options = parse_config(config)
    ref = compute("uniform", view, light, scene, options)
    assert np.allclose(out["maps"][0]["matrix"], ref.maps[0].matrix, rtol=1e-12, atol=1e-15)
    assert out["maps"][0]["size"] == [1024, 1024]
    d = out["diagnostics"]
    assert d["theta_deg"] == pytest.approx(math.degrees(ref.diagnostics.theta))
    assert len(d["body_vertices"]) == len(ref.diagnostics.body_vertices)


def test_empty_body_is_reported_not_crashed_on():
    config = base_config()
    config["camera"]["matrix_world"] = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 50], [0, 0, 0, 1]]  # looks down -Z from 50 m up... at the ground
    config["boxes"] = [{"min": [500, 500, 0], "max": [501, 501, 1]}]                            # ...which is elsewhere
    r = run_cli("--method", "all", "-", stdin=json.dumps(config))
    assert r.returncode == 0, r.stderr
    assert r.stderr.count("\n") == 1 and "empty" in r.stderr
    out = json.loads(r.stdout)
    for obj in out["methods"].values():
        assert obj["maps"] == [] and "receiver" in obj["diagnostics"]["empty_body"]
    r = run_cli("--method", "uniform", "-", stdin=json.dumps(config))
    assert r.returncode == 0 and json.loads(r.stdout)["diagnostics"]["empty_body"]


def test_no_boxes_is_an_empty_body():
    config = base_config()
    config["boxes"] = []
    r = run_cli("--method", "uniform", "-", stdin=json.dumps(config))
    assert r.returncode == 0
    assert "no shadow casters or receivers" in json.loads(r.stdout)["diagnostics"]["empty_body"]


# ----------------------------------------------------------------------------- malformed input

def _set(path, value):
    def f(c):
        obj = c
        for k in path[:-1]:
            obj = obj[k]
        obj[path[-1]] = value
    return f


def _drop(path):
    def f(c):
        obj = c
        for k in path[:-1]:
            obj = obj[k]
        del obj[path[-1]]
    return f


MALFORMED = {
    # name: (mutation, the field the one-line error must name)
    "camera_missing": (_drop(["camera"]), "camera"),
    "camera_not_an_object": (_set(["camera"], 5), "camera"),
    "matrix_missing": (_drop(["camera", "matrix_world"]), "camera.matrix_world"),
    "matrix_3x3": (_set(["camera", "matrix_world"], [[1, 0, 0], [0, 1, 0], [0, 0, 1]]), "camera.matrix_world"),
    "matrix_string": (_set(["camera", "matrix_world"], "eye"), "camera.matrix_world"),
    "matrix_nan": (_set(["camera", "matrix_world"], [[float("nan")] * 4] * 4), "camera.matrix_world"),
    "matrix_ragged": (_set(["camera", "matrix_world"], [[1, 2], [1, 2, 3, 4], [0, 0, 1, 0], [0, 0, 0, 1]]),
                      "camera.matrix_world"),
    "matrix_objects": (_set(["camera", "matrix_world"], [[{"a": 1}] * 4] * 4), "camera.matrix_world"),
    "matrix_singular": (_set(["camera", "matrix_world"], [[0, 0, 0, 0]] * 3 + [[0, 0, 0, 1]]), "camera.matrix_world"),
    "matrix_projective_row": (_set(["camera", "matrix_world"], [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]]),
                              "camera.matrix_world"),
    "fov_missing": (_drop(["camera", "fov_y_deg"]), "camera.fov_y_deg"),
    "fov_zero": (_set(["camera", "fov_y_deg"], 0), "camera.fov_y_deg"),
    "fov_180": (_set(["camera", "fov_y_deg"], 180), "camera.fov_y_deg"),
    "fov_string": (_set(["camera", "fov_y_deg"], "60"), "camera.fov_y_deg"),
    "fov_bool": (_set(["camera", "fov_y_deg"], True), "camera.fov_y_deg"),
    "near_negative": (_set(["camera", "near"], -1), "camera.near"),
    "near_beyond_far": (_set(["camera", "near"], 100), "camera.far"),
    "far_infinite": (_set(["camera", "far"], float("inf")), "camera.far"),
    "far_missing": (_drop(["camera", "far"]), "camera.far"),
    "aspect_zero": (_set(["camera", "aspect"], 0), "camera.aspect"),
    "resolution_float": (_set(["camera", "resolution"], [1280.5, 720]), "camera.resolution"),
    "resolution_negative": (_set(["camera", "resolution"], [-1, 720]), "camera.resolution"),
    "resolution_absurd": (_set(["camera", "resolution"], [10 ** 9, 720]), "camera.resolution"),
    "resolution_three": (_set(["camera", "resolution"], [1, 2, 3]), "camera.resolution"),
    "ortho_without_height": (_set(["camera", "orthographic"], True), "camera.ortho_height"),
    "ortho_not_bool": (_set(["camera", "orthographic"], "yes"), "camera.orthographic"),
    "light_missing": (_drop(["light"]), "light"),
    "light_type_area": (_set(["light", "type"], "AREA"), "light.type"),
    "light_type_lowercase": (_set(["light", "type"], "sun"), "light.type"),
    "light_type_missing": (_drop(["light", "type"]), "light.type"),
    # a light's name was str()'d: 5, null or "" computed as light '5', 'None' or '' in every message
    "light_name_number": (_set(["light", "name"], 5), "light.name"),
    "light_name_null": (_set(["light", "name"], None), "light.name"),
    "light_name_empty": (_set(["light", "name"], " "), "light.name"),
    "light_direction_zero": (_set(["light", "direction"], [0, 0, 0]), "light.direction"),
    "light_direction_two": (_set(["light", "direction"], [0, 1]), "light.direction"),
    "light_direction_string": (_set(["light", "direction"], "down"), "light.direction"),
    "light_direction_missing": (_drop(["light", "direction"]), "light.direction"),
    "point_without_position": (_set(["light"], {"type": "POINT"}), "light.position"),
    "point_position_nan": (_set(["light"], {"type": "POINT", "position": [0, float("nan"), 1]}), "light.position"),
    "spot_without_angle": (_set(["light"], {"type": "SPOT", "position": [0, 0, 5], "direction": [0, 0, -1]}),
                           "light.spot_angle_deg"),
    "spot_angle_200": (_set(["light"], {"type": "SPOT", "position": [0, 0, 5], "direction": [0, 0, -1],
                                        "spot_angle_deg": 200}), "light.spot_angle_deg"),
    "boxes_missing": (_drop(["boxes"]), "boxes"),
    "boxes_object": (_set(["boxes"], {"min": [0, 0, 0]}), "boxes"),
    "box_without_max": (_drop(["boxes", 0, "max"]), "boxes[0].max"),
    "box_inverted": (_set(["boxes", 0, "min"], [100, 100, 100]), "boxes[0]"),
    "box_not_an_object": (_set(["boxes", 0], [1, 2, 3]), "boxes[0]"),
    "box_string_coordinate": (_set(["boxes", 0, "min"], ["a", 0, 0]), "boxes[0].min"),
    "box_infinite": (_set(["boxes", 1, "max"], [1, 1, float("inf")]), "boxes[1].max"),
    "size_zero": (_set(["shadow_map_size"], 0), "shadow_map_size"),
    "size_float": (_set(["shadow_map_size"], 1024.0), "shadow_map_size"),
    "size_string": (_set(["shadow_map_size"], "1024"), "shadow_map_size"),
    "size_absurd": (_set(["shadow_map_size"], 10 ** 6), "shadow_map_size"),
    "size_three": (_set(["shadow_map_size"], [1, 2, 3]), "shadow_map_size"),
    "options_not_an_object": (_set(["options"], [1]), "options"),
    "option_unknown": (_set(["options"], {"foo": 1}), "options.foo"),
    "option_delta_z": (_set(["options"], {"delta_z": "far"}), "options.delta_z"),
    "option_lam_string": (_set(["options"], {"lam": "x"}), "options.lam"),
    "option_linear_z_string": (_set(["options"], {"linear_z": "yes"}), "options.linear_z"),
    "option_snapping_number": (_set(["options"], {"texel_snapping": 3}), "options.texel_snapping"),
    "option_depth_range_short": (_set(["options"], {"visible_depth_range": [1]}), "options.visible_depth_range"),
    "option_depth_range_string": (_set(["options"], {"visible_depth_range": "near"}), "options.visible_depth_range"),
    "option_depth_range_reversed": (_set(["options"], {"visible_depth_range": [5, 1]}), "options.visible_depth_range"),
    "option_depth_range_negative": (_set(["options"], {"visible_depth_range": [-5, 10]}), "options.visible_depth_range"),
    "option_depth_range_empty": (_set(["options"], {"visible_depth_range": [5, 5]}), "options.visible_depth_range"),
    "option_lam_negative": (_set(["options"], {"lam": -1}), "options.lam"),
    "option_lam_zero": (_set(["options"], {"lam": 0}), "options.lam"),
    "option_budget_string": (_set(["options"], {"plane_budget": "x"}), "options.plane_budget"),
    "option_budget_zero": (_set(["options"], {"plane_budget": 0}), "options.plane_budget"),
    "option_angle_negative": (_set(["options"], {"max_frustum_angle": -5}), "options.max_frustum_angle"),
    "option_angle_400": (_set(["options"], {"max_frustum_angle": 400}), "options.max_frustum_angle"),
    "planes_object": (_set(["planes"], {"point": [0, 0, 0]}), "planes"),
    "plane_without_normal": (_set(["planes"], [{"point": [0, 0, 0]}]), "planes[0].normal"),
    "plane_zero_normal": (_set(["planes"], [{"point": [0, 0, 0], "normal": [0, 0, 0]}]), "planes[0].normal"),
    "plane_not_an_object": (_set(["planes"], [[0, 0, 0]]), "planes[0]"),
    "plane_extent_two_points": (_set(["planes"], [{"point": [0, 0, 0], "normal": [0, 0, 1],
                                                   "extent": [[0, 0, 0], [1, 0, 0]]}]), "planes[0].extent"),
    "plane_extent_nan": (_set(["planes"], [{"point": [0, 0, 0], "normal": [0, 0, 1],
                                            "extent": [[0, 0, 0], [1, 0, 0], [0, float("nan"), 0]]}]),
                         "planes[0].extent[2]"),
    # keys the format does not know, or that do not apply, are refused by name (issue 14)
    "light_energy": (_set(["light", "energy"], 3.0), "light.energy"),
    "camera_unknown_key": (_set(["camera", "lens_mm"], 50), "camera.lens_mm"),
    "top_level_unknown_key": (_set(["lights"], []), "lights"),
    "box_unknown_key": (_set(["boxes", 0, "centre"], [0, 0, 0]), "boxes[0].centre"),
    "plane_unknown_key": (_set(["planes"], [{"point": [0, 0, 0], "normal": [0, 0, 1], "up": 1}]), "planes[0].up"),
    "sun_with_position": (_set(["light", "position"], [0, 0, 10]), "light.position"),
    "point_with_direction": (_set(["light"], {"type": "POINT", "position": [0, 0, 5], "direction": [0, 0, -1]}),
                             "light.direction"),
    "perspective_with_ortho_height": (_set(["camera", "ortho_height"], 5), "camera.ortho_height"),
    # numbers beyond floating point: a clear message naming the field, not "internal error"
    "aspect_1e-300": (_set(["camera", "aspect"], 1e-300), "camera.aspect"),
    "aspect_1e300": (_set(["camera", "aspect"], 1e300), "camera.aspect"),
    "matrix_1e300": (_set(["camera", "matrix_world"], [[1e300, 0, 0, 0], [0, 1e300, 0, 0], [0, 0, 1e300, 1e300],
                                                       [0, 0, 0, 1]]), "camera.matrix_world"),
    "matrix_position_1e300": (_set(["camera", "matrix_world"], [[1, 0, 0, 0], [0, 1, 0, 1e300], [0, 0, 1, 0],
                                                                [0, 0, 0, 1]]), "camera.matrix_world"),
    "matrix_axes_1e-300": (_set(["camera", "matrix_world"], [[1e-300, 0, 0, 0], [0, 1e-300, 0, 0],
                                                             [0, 0, 1e-300, 0], [0, 0, 0, 1]]), "camera.matrix_world"),
    "fov_1e-300": (_set(["camera", "fov_y_deg"], 1e-300), "camera"),
    "box_1e300": (_set(["boxes", 1, "max"], [1, 1, 1e300]), "boxes[1].max"),
    "point_position_1e300": (_set(["light"], {"type": "POINT", "position": [0, 1e300, 1]}), "light.position"),
    # a perspective clip range beyond 32-bit float depth: refused as the Blender path refuses it, not "empty body"
    "clip_range_1e13": (_set(["camera", "far"], 1e12), "camera.far"),
}


def malformed(name):
    mutate, field = MALFORMED[name]
    config = base_config()
    config["boxes"] = config["boxes"][:3]
    mutate(config)
    return json.dumps(config), field


def check_one_line(code, stdout, stderr, field):
    assert code == 2, (code, stdout[:200], stderr)
    assert "Traceback" not in stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert lines[0].startswith("lixel: error: ")
    assert field in lines[0], f"{lines[0]!r} should name {field!r}"
    assert stdout == ""


@pytest.mark.parametrize("name", list(MALFORMED))
def test_malformed_config_gets_one_line_naming_the_field(name, tmp_path, capsys):
    """In-process (fast) for every malformed config: ``main`` returns 2 and
    prints one line; an exception escaping ``main`` would fail the test."""
    from addon.cli import main
    text, field = malformed(name)
    path = tmp_path / "config.json"
    path.write_text(text)
    for method in ("uniform", "all"):
        code = main(["--method", method, str(path)])
        out = capsys.readouterr()
        check_one_line(code, out.out, out.err, field)


@pytest.mark.parametrize("field, value, unit", [("resolution", [10 ** 9, 720], "pixels"),
                                                ("shadow_map_size", [1024, 0], "texels")])
def test_a_size_out_of_range_names_what_it_counts(tmp_path, capsys, field, value, unit):
    """A camera resolution out of range was refused as "must be between 1 and 16384 texels per side": a camera has
    pixels; the shadow map's texels."""
    from addon.cli import main
    config = json.loads(EXAMPLES[0].read_text())
    (config["camera"] if field == "resolution" else config)[field] = value
    path = tmp_path / "config.json"
    path.write_text(json.dumps(config))
    assert main(["--method", "uniform", str(path)]) == 2
    where = f"camera.{field}" if field == "resolution" else field
    assert capsys.readouterr().err == f"lixel: error: {where}: must be between 1 and 16384 {unit} per side (got {value})\n"


BUDGET_RANGE = ("must be from 0.01 to 1, as in the Lixel panel: the share of the texel budget the plane maps may "
                "take")


@pytest.mark.parametrize("option, value, allowed", [
    ("lam", -1, "must be positive"), ("lam", 0, "must be positive"),
    ("visible_depth_range", [-5, 10], "must be [near, far] eye depths with 0 <= near < far"),
    ("visible_depth_range", [5, 5], "must be [near, far] eye depths with 0 <= near < far"),
    ("plane_budget", 1.5, BUDGET_RANGE), ("plane_budget", 1e-12, BUDGET_RANGE), ("plane_budget", 0.005, BUDGET_RANGE)])
def test_an_option_out_of_range_is_refused_before_computing(tmp_path, capsys, option, value, allowed):
    """A forced λ of -1 or 0 was read, then refused by GMNPR, GLPR and the cascade only ("gmnpr: the forced λ must
    be positive", exit 1) and ignored by every other method; a Visible Range from -5 (or from 5 to 5) computed
    silently, where the Lixel panel refuses it; plane_budget 1.5 was refused without its value, and 1e-12 or 0.005
    taken where the panel's Plane Budget goes from 0.01 to 1 (``config.PLANE_BUDGET``, read by both). Each is refused
    as the config is read, for every method, naming the option, the value and the range it must lie in."""
    from addon.cli import main
    config = base_config()
    config["options"] = {option: value}
    path = tmp_path / "config.json"
    path.write_text(json.dumps(config))
    for method in ("uniform", "gmnpr", "all"):
        assert main(["--method", method, str(path)]) == 2
        assert capsys.readouterr().err == f"lixel: error: options.{option}: {allowed} (got {value!r})\n"


@pytest.mark.parametrize("depths", [[1000, 2000], [0, 0.05]])
def test_a_visible_range_outside_the_clip_range_is_refused_as_read(tmp_path, capsys, depths):
    """outdoor_sun's camera clips at [0.1, 70]. A visible_depth_range of [1000, 2000] (or [0, 0.05]) holds nothing
    it sees: every method but the cascade ignored it silently, and the cascade failed with "no split of the view
    holds a visible receiver", naming no cause. Now it is refused as the config is read, for every method, naming
    the option, its value, the clip range and what to do."""
    from addon.cli import main
    config = base_config()
    config["options"] = {"visible_depth_range": depths, "delta_z": "visible"}
    path = tmp_path / "config.json"
    path.write_text(json.dumps(config))
    for method in ("uniform", "lispsm", "cascade", "all"):
        assert main(["--method", method, str(path)]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"lixel: error: options.visible_depth_range: [{depths[0]:g}, {depths[1]:g}] lies "
                              f"wholly outside the camera's clip range [0.1, 70]"), err
        assert "give eye depths that overlap the clip range, or drop the option" in err and err.count("\n") == 1


def test_a_visible_range_partly_outside_the_clip_range_is_clamped_by_every_method(tmp_path, capsys):
    """[20, 2000] overlaps outdoor_sun's clip range [0.1, 70]: every method takes its part within it, as the
    panel's default Visible Range (0.1 to 100 m) beside a camera clipping at 30 m must work."""
    from addon.cli import main
    config = base_config()
    config["options"] = {"visible_depth_range": [20, 2000], "delta_z": "visible"}
    path = tmp_path / "config.json"
    path.write_text(json.dumps(config))
    assert main(["--method", "all", str(path)]) == 0, capsys.readouterr().err
    results = json.loads(capsys.readouterr().out)["methods"]
    assert len(results) == 7 and all(r["maps"] for r in results.values())


def test_a_cascade_with_no_receiver_in_the_visible_range_names_the_range(tmp_path, capsys):
    """[65, 70] lies within outdoor_sun's clip range but holds no receiver it sees: the cascade, which splits only the
    range, said "no split of the view holds a visible receiver", naming no cause; now it names the option."""
    from addon.cli import main
    config = base_config()
    config["options"] = {"visible_depth_range": [65, 70]}
    path = tmp_path / "config.json"
    path.write_text(json.dumps(config))
    assert main(["--method", "cascade", str(path)]) == 1
    assert capsys.readouterr().err == (
        "lixel: error: cascade: no split of the view holds a visible receiver within options.visible_depth_range "
        "[65.0, 70.0]: widen it to the receivers' eye depths or drop the option\n")
    assert main(["--method", "uniform", str(path)]) == 0            # (which does not split by it)


@pytest.mark.parametrize("size, options, budget", [(1, {}, "0.75"), (1, {"plane_budget": 0.01}, "0.01")])
def test_plane_maps_that_do_not_fit_say_what_to_do(tmp_path, capsys, size, options, budget):
    """chess_spot at "shadow_map_size": 1 (the format's least): plane_optimal said "plane_optimal: plane_optimal:
    could not fit the plane maps into the texel budget", its name twice and no remedy. At a plane_budget of 1e-12
    of a 1024² map it said "give a larger shadow map size": one of 10^12 texels (that budget is now refused as read,
    as the panel refuses it). Either raises the budget."""
    from addon.cli import main
    config = json.loads((ROOT / "examples" / "chess_spot.json").read_text())
    config["shadow_map_size"], config["options"] = size, options
    path = tmp_path / "config.json"
    path.write_text(json.dumps(config))
    assert main(["--method", "plane_optimal", str(path)]) == 1
    assert capsys.readouterr().err == (f"lixel: error: plane_optimal: the plane maps do not fit a budget of {budget} "
                                       f"texels: raise the map size or plane budget\n")


@pytest.mark.parametrize("key, value", [("shadow_map_size", 1024), ("planes", [])])
def test_a_top_level_key_given_in_options_says_where_it_belongs(tmp_path, capsys, key, value):
    """"options": {"shadow_map_size": 1024} was refused as "unknown option; known: ..." with a list that does not
    hold it, though the config format takes it: at the top level. The line says so."""
    from addon.cli import main
    config = base_config()
    config["options"] = {key: value}
    path = tmp_path / "config.json"
    path.write_text(json.dumps(config))
    assert main(["--method", "uniform", str(path)]) == 2
    assert capsys.readouterr().err == (f"lixel: error: options.{key}: give {key} at the config's top level, "
                                       f"beside \"options\"\n")


@pytest.mark.parametrize("huge, unit", [([1e308, 0, 0], [1, 0, 0]), ([0, 0, -1e-320], [0, 0, -1]),
                                        ([1e308, 1e308, -1e308], [1, 1, -1])])
def test_a_light_direction_of_huge_or_tiny_numbers_is_the_direction_it_points(tmp_path, capsys, huge, unit):
    """A sun direction of [1e308, 0, 0] was refused as "not a non-zero vector" (its norm overflows to infinity) and
    [0, 0, -1e-320] likewise (its norm underflows); the core scales a vector by its largest component before
    normalising (geometry.normalize), and the CLI asks it: each gives the maps of the direction it points."""
    from addon.cli import main
    for direction in (huge, unit):
        config = base_config()
        config["light"]["direction"] = direction
        path = tmp_path / "config.json"
        path.write_text(json.dumps(config))
        assert main(["--method", "lispsm", str(path)]) == 0
        out = capsys.readouterr()
        assert out.err == ""
        maps = json.loads(out.out)["maps"]
        if direction is huge:
            expected = maps
    assert maps == expected


def test_clip_range_is_refused_beyond_what_float32_depth_resolves(tmp_path, capsys):
    """The rule of the Blender path (``MAX_CLIP_RATIO``, 1:2^24): up to it a perspective camera gets its maps, beyond
    it one line naming camera.far and what to do (a 1:1e12 range silently printed no maps, "empty body"); an
    orthographic camera's depth is linear, so any range computes."""
    from addon.cli import main
    from addon.warp.types import MAX_CLIP_RATIO
    path = tmp_path / "config.json"
    for far_over_near, ortho, ok in ((MAX_CLIP_RATIO, False, True), (MAX_CLIP_RATIO * 1.001, False, False),
                                     (1e12, False, False), (1e12, True, True)):
        config = base_config()
        config["camera"]["far"] = config["camera"]["near"] * far_over_near
        if ortho:
            config["camera"].update(orthographic=True, ortho_height=40.0)
            del config["camera"]["fov_y_deg"]
        path.write_text(json.dumps(config))
        code = main(["--method", "lispsm", str(path)])
        out = capsys.readouterr()
        if ok:
            assert code == 0 and json.loads(out.out)["maps"], (far_over_near, ortho, out.err)
        else:
            check_one_line(code, out.out, out.err, "camera.far")
            assert "raise camera.near or lower camera.far" in out.err


SUBPROCESS_SAMPLE = ["camera_missing", "matrix_nan", "matrix_projective_row", "fov_string", "near_beyond_far",
                     "light_type_area", "option_lam_negative", "box_inverted", "size_absurd", "option_lam_string",
                     "option_depth_range_short", "plane_zero_normal", "light_energy", "aspect_1e-300", "matrix_1e300"]


@pytest.mark.parametrize("name", SUBPROCESS_SAMPLE)
def test_malformed_config_in_a_real_process(name):
    text, field = malformed(name)
    r = run_cli("--method", "all", "-", stdin=text)
    check_one_line(r.returncode, r.stdout, r.stderr, field)


@pytest.mark.parametrize("where", [["camera"], []])
def test_a_key_given_twice_is_refused_not_silently_the_last(tmp_path, capsys, where):
    """A config with "far": 70 and, further down the camera, "far": 7 (or two "light" objects) computed the last one
    without a word (Python's JSON keeps the last); it is refused naming the key."""
    from addon.cli import main
    config = base_config()
    obj = config
    for key in where:
        obj = obj[key]
    key = "far" if where else "light"
    text = json.dumps(config)
    doubled = json.dumps(obj)[:-1] + f', "{key}": ' + json.dumps(obj[key]) + "}"
    path = tmp_path / "config.json"
    path.write_text(text.replace(json.dumps(obj), doubled) if where else doubled)
    assert main(["--method", "uniform", str(path)]) == 2
    assert capsys.readouterr().err == (f"lixel: error: config: the key '{key}' appears twice in one object (JSON keeps "
                                       f"the last, silently): keep one\n")


@pytest.mark.parametrize("text,expect", [
    ("", "not valid JSON"),
    ("{", "not valid JSON"),
    ("[1, 2]", "config: must be a JSON object"),
    ("null", "config: must be a JSON object"),
    ("\"camera\"", "config: must be a JSON object"),
    ("[" * 100000 + "]" * 100000, "config"),
    ('{"shadow_map_size": ' + "9" * 5000 + "}", "config: not valid JSON"),
], ids=["empty", "unclosed", "list", "null", "string", "deeply_nested", "number_beyond_pythons_digit_limit"])
def test_not_a_config_at_all(text, expect):
    r = run_cli("--method", "all", "-", stdin=text)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and expect in r.stderr


@pytest.mark.parametrize("stdin", [False, True], ids=["file", "stdin"])
def test_a_config_saved_with_a_byte_order_mark_reads_as_without(tmp_path, stdin):
    """Windows editors (Notepad, PowerShell's Out-File) save UTF-8 with a byte order mark: the config is the same."""
    example = ROOT / "examples" / "outdoor_sun.json"
    text = example.read_text(encoding="utf-8")
    plain = run_cli("--method", "uniform", str(example))
    if stdin:
        r = run_cli("--method", "uniform", "-", stdin="\ufeff" + text)
    else:
        path = tmp_path / "bom.json"
        path.write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
        r = run_cli("--method", "uniform", str(path))
    assert r.returncode == 0, r.stderr
    assert r.stdout == plain.stdout


def test_unreadable_files(tmp_path):
    r = run_cli("--method", "all", str(tmp_path / "missing.json"))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "cannot read" in r.stderr
    r = run_cli("--method", "all", str(tmp_path))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "cannot read" in r.stderr
    binary = tmp_path / "binary.json"
    binary.write_bytes(b"\xff\xfe\x00garbage")
    r = run_cli("--method", "all", str(binary))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr



def _cli_command(*args):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    env.pop("LIXEL_DEBUG", None)
    return [PLAIN_PYTHON, "-m", "addon.warp", *args], env


def test_a_reader_that_stops_early_gets_no_traceback():
    """``python -m addon.warp ... | head``: the reader closes the pipe; the command ends without a traceback."""
    read_end, write_end = os.pipe()
    os.close(read_end)                                   # a reader that has already stopped
    cmd, env = _cli_command("--method", "all", str(EXAMPLES[0]))
    try:
        r = subprocess.run(cmd, stdout=write_end, stderr=subprocess.PIPE, text=True, cwd=ROOT, env=env, timeout=120)
    finally:
        os.close(write_end)
    assert r.returncode == 1 and r.stderr == "", r.stderr


def test_ctrl_c_while_waiting_for_the_config_is_one_line():
    """``python -m addon.warp --method all -`` with no config piped in waits on standard input; Ctrl-C there printed
    a traceback (from a codec's decode) and the process died of the signal. One line, status 130."""
    import signal
    import time
    cmd, env = _cli_command("--method", "all", "-")
    p = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         cwd=ROOT, env=env, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    # (the child gets SIGINT's default action, as a terminal's foreground job: a suite run in the background passes
    # it on ignored, and Python then never raises KeyboardInterrupt)
    for _ in range(200):   # until it reads its standard input (Linux: syscall 0, read, of descriptor 0)
        try:
            if open(f"/proc/{p.pid}/syscall").read().startswith("0 0x0 "):
                break
        except OSError:
            time.sleep(3)
            break
        time.sleep(0.05)
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=60)
    assert (p.returncode, out, err) == (130, "", "lixel: interrupted: nothing written\n")


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
def test_output_to_a_full_disk_is_one_line_naming_it():
    cmd, env = _cli_command("--method", "uniform", str(EXAMPLES[0]))
    with open("/dev/full", "w") as full:
        r = subprocess.run(cmd, stdout=full, stderr=subprocess.PIPE, text=True, cwd=ROOT, env=env, timeout=120)
    assert r.returncode == 1 and r.stderr == "lixel: error: cannot write the output: No space left on device\n", \
        r.stderr

@pytest.mark.parametrize("value", ["-1", "-20", "17", "1000000000", "2.5", "two"])
def test_indent_out_of_range_is_one_line_naming_it(value):
    """--indent is a number of spaces, 0..16: a negative one printed as if it were 0 (json treats it as ''),
    and a huge one padded every line with it (a gigabyte of spaces for 10^9)."""
    r = run_cli("--method", "uniform", str(EXAMPLES[0]), "--indent", value)
    assert r.returncode == 2 and r.stdout == "", r.stdout[:200]
    assert "argument --indent: " in r.stderr and "0 to 16" in r.stderr and "Traceback" not in r.stderr, r.stderr


@pytest.mark.parametrize("value", ["0", "2", "16"])
def test_indent_in_range_pretty_prints(value):
    r = run_cli("--method", "uniform", str(EXAMPLES[0]), "--indent", value)
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines()[1] == " " * int(value) + '"maps": ['


def test_unknown_method():
    r = run_cli("--method", "nope", str(EXAMPLES[0]))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "--method" in r.stderr


def test_a_broken_method_does_not_hide_the_others(tmp_path):
    """A bug in one method is one line in its diagnostics; the rest still print."""
    script = tmp_path / "run.py"
    script.write_text(
        "import sys, runpy\n"
        "from addon.warp import METHODS\n"
        "def broken(*a):\n    raise ZeroDivisionError('boom')\n"
        "METHODS['uniform'] = broken\n"
        "sys.argv = ['addon.warp', '--method', 'all', sys.argv[1]]\n"
        "runpy.run_module('addon.warp', run_name='__main__')\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("LIXEL_DEBUG", None)
    r = subprocess.run([PLAIN_PYTHON, str(script), str(EXAMPLES[0])], capture_output=True, text=True, cwd=ROOT, env=env)
    assert r.returncode == 0 and "Traceback" not in r.stderr
    out = json.loads(r.stdout)["methods"]
    assert "ZeroDivisionError" in out["uniform"]["diagnostics"]["error"]
    assert all(out[m]["maps"] for m in out if m != "uniform")


@pytest.mark.parametrize("degrees", [0.5, 9.9, 170.5, 175, 179.999])
def test_a_max_frustum_angle_the_panel_refuses_is_refused_with_its_range(tmp_path, capsys, degrees):
    """The Lixel panel takes Max Frustum Angle from 10° to 170°; the CLI took any angle in (0°, 180°): at 179.999°
    a point light got one perspective map whose centre texels are 114,592 times as wide as a 90° cube face's (the panel
    would have given cube faces). One range (``cli.config.FRUSTUM_ANGLE_DEGREES``) for both, refused with it."""
    from addon.cli import main
    config = json.loads((ROOT / "examples" / "terrain_point.json").read_text())
    config["options"] = {"max_frustum_angle": degrees}
    path = tmp_path / "config.json"
    path.write_text(json.dumps(config))
    assert main(["--method", "uniform", str(path)]) == 2
    assert capsys.readouterr().err == (f"lixel: error: options.max_frustum_angle: must be from 10 to 170 degrees, as "
                                       f"in the Lixel panel; wider lights take cube faces (got {degrees!r})\n")


@pytest.mark.parametrize("degrees", [10, 170])
def test_the_panels_max_frustum_angles_compute_from_the_cli(tmp_path, capsys, degrees):
    from addon.cli import main
    config = json.loads((ROOT / "examples" / "terrain_point.json").read_text())
    config["options"] = {"max_frustum_angle": degrees}
    path = tmp_path / "config.json"
    path.write_text(json.dumps(config))
    assert main(["--method", "uniform", str(path)]) == 0
    assert json.loads(capsys.readouterr().out)["maps"]


def test_plane_optimal_names_the_receiver_it_speaks_of_as_the_configs_box(tmp_path, capsys):
    """plane_optimal's notes named "receiver box i", i counting only the boxes in view: with a box out of view first,
    the tower boxes[1] was "receiver box 0" and the ground boxes[2] "top of receiver box 1". They name boxes[k]."""
    from addon.cli import main
    config = json.loads((ROOT / "examples" / "sun_overhead.json").read_text())
    behind, tower, ground = ({"min": [0, -600, 0], "max": [1, -599, 1]}, {"min": [0, 0, 0], "max": [1, 1, 3]},
                             {"min": [-50, -50, -0.1], "max": [50, 50, 0]})
    for boxes, said in (([behind, tower], "the flattest, boxes[1], is 300%"), ([behind, tower, ground], None)):
        config["boxes"] = boxes
        path = tmp_path / "config.json"
        path.write_text(json.dumps(config))
        assert main(["--method", "plane_optimal", str(path)]) == 0
        d = json.loads(capsys.readouterr().out)["diagnostics"]
        assert "receiver box" not in json.dumps(d)
        if said:
            assert said in d["fallbacks"][0]["reason"]
        else:
            assert d["default_plane"] == "top of boxes[2]" and d["planes"][0]["name"] == "top of boxes[2]"


@pytest.mark.parametrize("scale", [(2.0, 2.0, 2.0), (0.5, 0.5, 0.5), (2.0, 4.0, 0.5)])
def test_a_scaled_camera_is_taken_as_blender_takes_it_unscaled(tmp_path, capsys, scale):
    """Blender's renderers ignore a camera's scale (``describe.unscaled_camera_matrix``); the CLI took it into the
    view, so a camera matrix_world scaled by 2 measured eye depths in halves (visible_depth_range 1.86-5.27 for
    chess_spot's 3.72-10.54) and clipped at twice its near and far; a non-uniform scale stretched the frustum."""
    from addon.cli import main
    config = json.loads((ROOT / "examples" / "chess_spot.json").read_text())
    unscaled = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, -8.0], [0.0, 1.0, 0.0, 1.0], [0.0, 0.0, 0.0, 1.0]])
    outputs = []
    for s in ((1.0, 1.0, 1.0), scale):
        matrix = unscaled.copy()
        matrix[:3, :3] *= s                          # (Blender's matrix_world: each axis times the object's scale)
        config["camera"]["matrix_world"] = matrix.tolist()
        path = tmp_path / "config.json"
        path.write_text(json.dumps(config))
        assert main(["--method", "all", str(path)]) == 0
        outputs.append(capsys.readouterr().out)
    assert outputs[0] == outputs[1]


@pytest.mark.parametrize("scale", [1e-300, 1e300])
def test_a_plane_normal_of_any_finite_length_is_a_direction(tmp_path, capsys, scale):
    """A plane's normal [0, 0, 1e-300] or [0, 0, 1e300] was divided by its length in float64 (which under- or
    overflows: 0 or inf) and plane_optimal failed with "needs a finite point and a non-zero finite normal" (exit 1),
    while light.direction [1e308, 0, 0] is a direction (the core's ``normalize``). Now both are read as the core
    reads a direction: the maps equal those of [0, 0, 1]."""
    from addon.cli import main
    config = json.loads((ROOT / "examples" / "chess_spot.json").read_text())
    outputs = []
    for normal in ([0, 0, 1], [0, 0, scale]):
        config["planes"] = [{"point": [0, 0, 0], "normal": normal}]
        path = tmp_path / "config.json"
        path.write_text(json.dumps(config))
        assert main(["--method", "plane_optimal", str(path)]) == 0, capsys.readouterr().err
        outputs.append(json.loads(capsys.readouterr().out)["maps"])
    assert outputs[0] == outputs[1]
