"""The background scripts run both ways - ``python scripts/X.py file.blend args``
with the bpy module, and as Blender runs them (``blender -b file.blend --python
scripts/X.py -- args``, reproduced with the bpy module: the file is opened first
and the arguments follow ``--``) - with good arguments (correct output) and bad
ones (usage, non-zero exit), on both Blender versions, exiting cleanly."""
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import bpy
import numpy as np
import pytest

from ui_scenes import active_scene

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = ROOT / "scripts"

BLENDER_MODE = """
import runpy, sys
import bpy
bpy.ops.wm.open_mainfile(filepath=sys.argv[1])
script = sys.argv[2]
sys.argv = ["blender", "-b", sys.argv[1], "--python", script, "--"] + sys.argv[3:]
runpy.run_path(script, run_name="__main__")
"""


@pytest.fixture(scope="module")
def blend(tmp_path_factory, lixel):
    """A tiny .blend: ground, cube, camera moving over 5 frames, sun."""
    path = tmp_path_factory.mktemp("blends") / "tiny.blend"
    with active_scene("tiny") as scene:
        cam = scene.camera
        cam.keyframe_insert("location", frame=1)
        cam.location.x -= 3.0
        cam.keyframe_insert("location", frame=5)
        scene.frame_start, scene.frame_end = 1, 5
        scene.lixel.pcf_kernel = 1
        bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    return path


def run(mode, script, blend_path, *args, timeout=240, cwd=ROOT, file_size_blocks=None):
    """Run a script as a user does (``mode``: the bpy module or ``blender --python``); ``file_size_blocks``: files
    may not grow past that many 512-byte blocks (a write fails part-way, as on a full disk)."""
    env = dict(os.environ)
    scratch = Path(blend_path).parent if blend_path else Path(tempfile.gettempdir())
    env.setdefault("XDG_CACHE_HOME", str(scratch / "xdg"))
    env.setdefault("BLENDER_USER_RESOURCES", str(scratch / "user"))
    script_path = str(SCRIPTS / script)
    if mode == "module":
        cmd = [sys.executable, script_path] + ([str(blend_path)] if blend_path else []) + list(args)
    else:
        cmd = [sys.executable, "-c", BLENDER_MODE, str(blend_path), script_path] + list(args)
    if file_size_blocks is not None:    # SIGXFSZ ignored: the write fails (EFBIG) instead of killing the process
        cmd = ["sh", "-c", f'trap "" XFSZ; ulimit -f {file_size_blocks}; exec "$@"', "sh", *cmd]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env, cwd=str(cwd))


MODES = ["module", "blender"]


@pytest.mark.parametrize("script, option, name, extra", [
    ("export_animation.py", "--output", "setup.json", ("--frames", "1:5")),
    ("render_method.py", "--json", "setup.json", ()),
    ("render_method.py", "--shadow-output", "shadow.exr", ("--resolution", "320x180"))])
def test_an_output_that_fails_part_way_leaves_the_file_that_was_there(blend, tmp_path, script, option, name, extra):
    """An output written over an existing file emptied it first: a write that failed part-way (a full disk) left
    the user's file gone and half a document or picture in its place. It is written beside it and renamed over it
    once whole; a failed one is one line naming the file, and leaves nothing behind."""
    out = tmp_path / name
    out.write_text('{"the user\'s": "earlier export"}\n')
    r = run("module", script, blend, option, str(out), "--method", "uniform", *extra, file_size_blocks=1)
    assert r.returncode == 1 and f"lixel: error: cannot write '{out}': " in r.stderr, r.stderr
    assert out.read_text() == '{"the user\'s": "earlier export"}\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]


@pytest.mark.parametrize("mode", MODES)
def test_export_animation(mode, blend, tmp_path):
    out = tmp_path / "anim.json"
    r = run(mode, "export_animation.py", blend, "--output", str(out), "--frames", "1:5:2", "--method", "uniform")
    assert r.returncode == 0, r.stderr
    doc = json.loads(out.read_text())
    assert doc["scene"] == "tiny" and doc["method"] == "uniform"
    assert [f["frame"] for f in doc["frames"]] == [1, 3, 5]
    first, last = doc["frames"][0], doc["frames"][-1]
    assert set(first) == {"frame", "maps", "diagnostics"}
    # the camera moves, so the (camera-fitted) matrices differ between frames
    assert not np.allclose(first["maps"][0]["matrix"], last["maps"][0]["matrix"])
    # B (diagnostics) contains the cube's top corners seen from every frame: it is B of the scene, in world space
    for f in doc["frames"]:
        body = np.array(f["diagnostics"]["body_vertices"])
        assert body[:, 2].max() >= 1.0 - 1e-6 and body[:, 2].min() <= 1e-6


EARLIER = '{"the user\'s": "earlier export"}\n'


@pytest.mark.parametrize("mode", MODES)
def test_export_animation_that_computes_no_frame_keeps_the_file_there(mode, blend, lixel, tmp_path):
    """A misspelt ``--camera`` was said once per frame and the user's earlier export was replaced by a document of
    errors alone ('0 of 5 frames exported to anim.json', then the error): it is said at once and nothing is
    written; a scene no frame of which can be computed (a camera clipping from 5 to 5) keeps the file too."""
    out = tmp_path / "anim.json"
    out.write_text(EARLIER)
    r = run(mode, "export_animation.py", blend, "--output", str(out), "--camera", "tiny camra")
    assert r.returncode == 1 and "lixel: error: there is no object named 'tiny camra'" in r.stderr, r.stderr
    assert "exported" not in r.stdout + r.stderr and out.read_text() == EARLIER
    with active_scene("tiny") as scene:
        scene.camera.data.clip_start = scene.camera.data.clip_end = 5.0
        bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "clipped.blend"), copy=True)
    r = run(mode, "export_animation.py", tmp_path / "clipped.blend", "--output", str(out), "--frames", "1:2")
    assert r.returncode == 1 and "lixel: error: no frame could be computed, nothing written: Camera" in r.stderr, \
        r.stderr
    assert out.read_text() == EARLIER and sorted(p.name for p in tmp_path.iterdir()) == ["anim.json", "clipped.blend"]


@pytest.mark.parametrize("options", [("--output", "--shadow-output"), ("--json", "--map-output")])
def test_two_outputs_naming_one_file_are_refused(blend, tmp_path, options):
    """``--output r.png --shadow-output r.png`` wrote the shaded picture, then the shadow mask over it, and said
    nothing: the user asked for two pictures and got one. Refused, naming both options; nothing written."""
    out = tmp_path / "r.png"
    args = [a for option in options for a in (option, str(out))]
    r = run("module", "render_method.py", blend, *args, "--resolution", "32x18")
    assert r.returncode == 1, r.stderr
    assert (f"lixel: error: {options[0]} and {options[1]} both name {out}: the second would overwrite the first; "
            f"give each its own file") in r.stderr, r.stderr
    assert not out.exists()


def _ctrl_c_as_in_a_terminal():
    """In the child: SIGINT's default action, as a terminal's foreground job has it (a suite run in the background,
    ``cmd &`` or a CI runner, passes SIGINT on ignored, and Python then never raises KeyboardInterrupt)."""
    import signal
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_is_one_line_and_leaves_the_file_there(blend, tmp_path):
    """Ctrl-C during a run printed a Python traceback (from wherever it landed: a GPU read-back, a picture's save)
    and ended by the signal; it is one line, status 130, and the file the run would have replaced is kept. (A Ctrl-C
    landing inside one of Blender's handlers is printed and dropped by Blender itself, as any exception there: the
    user presses it again, as this test does.)"""
    import signal
    import threading
    import time
    out = tmp_path / "anim.json"
    out.write_text(EARLIER)
    env = dict(os.environ, XDG_CACHE_HOME=str(tmp_path / "xdg"), BLENDER_USER_RESOURCES=str(tmp_path / "user"))
    p = subprocess.Popen([sys.executable, str(SCRIPTS / "export_animation.py"), str(blend), "--output", str(out),
                          "--frames", "1:1048574"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         env=env, cwd=str(ROOT), preexec_fn=_ctrl_c_as_in_a_terminal)
    err: list = []
    threading.Thread(target=lambda: err.extend(p.stderr), daemon=True).start()
    try:
        assert "Read blend" in p.stdout.readline()      # the file is open: the frames are being computed
        for _ in range(60):
            p.send_signal(signal.SIGINT)
            try:
                p.wait(timeout=2)
                break
            except subprocess.TimeoutExpired:
                continue
    finally:
        if p.poll() is None:      # (never left running a million frames when Ctrl-C did not end it)
            p.kill()
            p.wait()
    p.stdout.read()
    time.sleep(0.2)
    text = "".join(err)
    assert p.returncode == 130, text
    assert text.splitlines()[-1] == ("lixel: interrupted: the outputs written so far are whole; the one in progress "
                                     "was not written (a file already there under its name is kept)")
    assert "_lixel_script.py" not in text, text        # no traceback through the script's own code
    assert out.read_text() == EARLIER
    assert [f.name for f in tmp_path.iterdir() if f.name not in ("user", "xdg")] == ["anim.json"]


@pytest.mark.parametrize("script", ["compare_methods.py", "overlay_snapshot.py"])
def test_an_output_dir_that_is_a_file_is_refused_first(blend, tmp_path, script):
    """``--output-dir`` naming a file: compare_methods computed and printed every method, then said "cannot write
    'x': File exists". Refused first, saying it is a file; the file is kept."""
    there = tmp_path / "notes.txt"
    there.write_text("the user's notes\n")
    r = run("module", script, blend, "--output-dir", str(there), *(["--no-render"] if "compare" in script else []))
    assert r.returncode == 1 and f"lixel: error: --output-dir {there} is a file, not a folder: name a folder" \
        in r.stderr, r.stderr
    assert "texel px" not in r.stdout and there.read_text() == "the user's notes\n"


@pytest.mark.parametrize("script", ["compare_methods.py", "overlay_snapshot.py"])
def test_an_output_dir_that_cannot_be_written_is_refused_before_any_work(blend, tmp_path, script):
    """``--output-dir notes.txt/pictures`` (a file where a folder must be made): compare_methods computed and printed
    the whole table, then said "cannot write 'notes.txt/pictures': Not a directory". Refused first, naming the folder,
    why and what to do; nothing is made and the file is kept."""
    there = tmp_path / "notes.txt"
    there.write_text("the user's notes\n")
    folder = there / "pictures"
    r = run("module", script, blend, "--output-dir", str(folder), *(["--no-render"] if "compare" in script else []))
    assert r.returncode == 1 and (f"lixel: error: --output-dir {folder} cannot be written: {there} is a file, not a "
                                  f"folder: name a folder you can write to (one that is missing is made)") \
        in r.stderr, r.stderr
    assert "texel px" not in r.stdout and there.read_text() == "the user's notes\n"


def test_a_missing_output_dir_is_made_only_by_a_run_that_writes(blend, tmp_path):
    """The check makes nothing: a run refused for its arguments after it (an unknown method) leaves no folder."""
    folder = tmp_path / "new" / "pictures"
    r = run("module", "compare_methods.py", blend, "--output-dir", str(folder), "--no-render", "--methods", "bogus")
    assert r.returncode == 2 and not (tmp_path / "new").exists(), r.stderr


def test_export_animation_to_stdout_is_json_only(blend):
    """``--output -``: Blender's "Read blend" line (printed by C code when the
    script opens the file) and any note go to stderr; stdout parses as JSON."""
    r = run("module", "export_animation.py", blend, "--output", "-", "--frames", "1:3", "--method", "uniform")
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    assert [f["frame"] for f in doc["frames"]] == [1, 2, 3]
    assert "Read blend" in r.stderr or "Read" not in r.stdout


def _run_to(stdout, script, blend_path, *args):
    """``run("module", ...)`` with standard output going to ``stdout`` (a file descriptor or file)."""
    env = dict(os.environ)
    env.setdefault("XDG_CACHE_HOME", str(Path(blend_path).parent / "xdg"))
    env.setdefault("BLENDER_USER_RESOURCES", str(Path(blend_path).parent / "user"))
    return subprocess.run([sys.executable, str(SCRIPTS / script), str(blend_path), *args], stdout=stdout,
                          stderr=subprocess.PIPE, text=True, timeout=240, env=env, cwd=str(ROOT))


def test_export_animation_to_a_reader_that_stops_early_or_a_full_disk(blend):
    """``--output - | head`` ends quietly; a full disk is named as the output, not as a file called 'None'."""
    read_end, write_end = os.pipe()
    os.close(read_end)                                   # a reader that has already stopped
    try:
        r = _run_to(write_end, "export_animation.py", blend, "--output", "-", "--frames", "1:2")
    finally:
        os.close(write_end)
    assert r.returncode == 1 and "lixel: error" not in r.stderr and "Traceback" not in r.stderr, r.stderr
    if os.path.exists("/dev/full"):
        with open("/dev/full", "w") as full:
            r = _run_to(full, "export_animation.py", blend, "--output", "-", "--frames", "1:2")
        assert r.returncode == 1 and "lixel: error: cannot write the output: No space left on device" in r.stderr, \
            r.stderr

@pytest.mark.parametrize("mode", MODES)
def test_render_method_writes_pictures_and_json(mode, blend, tmp_path, load_pixels):
    png, mask, js = tmp_path / "r.png", tmp_path / "mask.png", tmp_path / "r.json"
    r = run(mode, "render_method.py", blend, "--method", "lispsm", "--resolution", "48x27", "--size", "256",
            "--output", str(png), "--shadow-output", str(mask), "--json", str(js))
    assert r.returncode == 0, r.stderr
    doc = json.loads(js.read_text())
    assert set(doc) == {"maps", "diagnostics"} and doc["maps"][0]["size"] == [256, 256]
    assert doc["diagnostics"]["method"] == "lispsm"
    px = load_pixels(mask)
    assert px.shape[:2] == (27, 48)
    shadowed = px[..., 0] > 0.5
    assert 0 < shadowed.sum() < shadowed.size  # the cube's shadow is there, not everything
    assert png.stat().st_size > 0


def test_render_method_draws_the_method_it_was_asked_for(blend, tmp_path, load_pixels):
    """The scene's own method is lispsm: ``--method uniform`` must render (and name) uniform's shadows, not the
    scene's, even though Lixel's live update recomputes the scene's own setup when the render starts."""
    masks = {}
    for method in ("uniform", "lispsm"):
        mask = tmp_path / f"{method}.png"
        r = run("module", "render_method.py", blend, "--method", method, "--resolution", "96x54", "--size", "64",
                "--shadow-output", str(mask))
        assert r.returncode == 0, r.stderr
        assert f"lixel: {method}: 1 map(s) of light 'tiny light', " in r.stdout, r.stdout  # which of a scene's lights
        masks[method] = load_pixels(mask)[..., 0] > 0.5
    assert (masks["uniform"] != masks["lispsm"]).sum() > 10


def test_a_picture_named_without_a_folder_goes_to_the_working_directory(blend, tmp_path):
    """``--output out.png`` (the usage line's own example): Blender 5.0 cannot save an image to a bare file name."""
    r = run("module", "render_method.py", blend, "--resolution", "32x18", "--output", "out.png",
            "--shadow-output", "./mask.png", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "out.png").stat().st_size > 0 and (tmp_path / "mask.png").stat().st_size > 0

def test_each_picture_is_written_in_the_format_its_name_ends_with(blend, tmp_path, load_pixels):
    """``--output r.exr`` wrote PNG data under the .exr name (the values above 1 clipped), which no EXR reader
    opens; every picture is now the format its ending names (PNG without one), and an ending Lixel does not
    write is refused before rendering, the file not made."""
    names = {"exr": "r.exr", "jpg": "mask.JPG", "tif": "map.tiff", "png": "plain"}
    r = run("module", "render_method.py", blend, "--resolution", "48x27", "--output", str(tmp_path / names["exr"]),
            "--shadow-output", str(tmp_path / names["jpg"]), "--map-output", str(tmp_path / names["tif"]))
    assert r.returncode == 0, r.stderr
    r = run("module", "render_method.py", blend, "--resolution", "48x27", "--output", str(tmp_path / names["png"]))
    assert r.returncode == 0, r.stderr
    magic = {"exr": b"\x76\x2f\x31\x01", "jpg": b"\xff\xd8\xff", "tif": b"II*\x00", "png": b"\x89PNG"}
    for kind, name in names.items():
        head = (tmp_path / name).read_bytes()[:4]
        assert head.startswith(magic[kind]) or (kind == "tif" and head == b"MM\x00*"), (name, head)
    assert load_pixels(tmp_path / names["exr"])[..., :3].max() > 1.0     # scene-linear, not clipped
    bad = tmp_path / "r.xyz"
    r = run("module", "render_method.py", blend, "--resolution", "48x27", "--output", str(bad))
    assert r.returncode == 1 and not bad.exists()
    assert (f"lixel: error: cannot write '{bad}': Lixel writes .png, .exr, .jpg, .jpeg, .tif, .tiff pictures, not "
            f".xyz: end the name with one of those") in r.stderr and "lispsm:" not in r.stdout, r.stderr


def test_a_resolution_of_another_shape_is_framed_as_blender_frames_it_not_stretched(blend, tmp_path, load_pixels):
    """The scene renders 640x360 with the sensor fitted automatically (to the wider side): at 96x96 Blender keeps
    the horizontal field of view and shows more above and below, so the middle 54 rows are the 96x54 picture."""
    pictures = {}
    for size in ("96x54", "96x96"):
        png = tmp_path / f"{size}.png"
        r = run("module", "render_method.py", blend, "--resolution", size, "--output", str(png))
        assert r.returncode == 0, r.stderr
        pictures[size] = load_pixels(png)[..., :3]
    assert pictures["96x96"].shape[:2] == (96, 96)
    same = np.isclose(pictures["96x96"][21:75], pictures["96x54"], atol=0.02).all(axis=-1)
    assert same.mean() > 0.99, same.mean()

@pytest.mark.parametrize("mode", MODES)
def test_compare_methods_numbers_only(mode, blend, tmp_path):
    out = tmp_path / "cmp"
    r = run(mode, "compare_methods.py", blend, "--output-dir", str(out), "--no-render", "--methods", "uniform,lispsm")
    assert r.returncode == 0, r.stderr
    doc = json.loads((out / "comparison.json").read_text())
    assert list(doc["methods"]) == ["uniform", "lispsm"]
    assert doc["methods"]["lispsm"]["n_opt"] > 0
    assert "uniform" in r.stdout and "lispsm" in r.stdout


@pytest.mark.parametrize("mode", MODES)
def test_a_blend_relative_output_is_written_beside_the_blend_file(mode, blend):
    """"//name" is Blender's "beside the .blend file" (as in ``blender -o //render_``): the JSON went to the file
    system's root, the picture beside the file."""
    names = [f"relative {mode}.json", f"relative {mode}.png"]
    try:
        r = run(mode, "render_method.py", blend, "--resolution", "16x9", "--json", f"//{names[0]}",
                "--output", f"//{names[1]}")
        assert r.returncode == 0, r.stderr
        assert all((Path(blend).parent / name).stat().st_size > 0 for name in names)
    finally:
        for name in names:
            for where in (Path(blend).parent, Path("/")):
                (where / name).unlink(missing_ok=True)

@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("option", ["--output", "--json"])
def test_an_output_naming_the_blend_file_itself_is_refused_and_the_file_kept(mode, blend, option):
    """A slip of the shell (``--output scene.blend``) must not turn the user's .blend file into a picture."""
    before = Path(blend).read_bytes()
    r = run(mode, "render_method.py", blend, "--resolution", "16x9", option, str(blend))
    assert r.returncode == 1 and f"lixel: error: {option} {blend} is the .blend file being read" in r.stderr, r.stderr
    assert Path(blend).read_bytes() == before

def test_compare_methods_names_the_camera_it_was_given(lixel, tmp_path):
    path = tmp_path / "two cameras.blend"
    with active_scene("two_cameras") as scene:
        side = bpy.data.objects.new("two_cameras side", scene.camera.data.copy())
        scene.collection.objects.link(side)
        side.matrix_world = scene.camera.matrix_world
        side.location.x -= 1.0
        bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    out = tmp_path / "cmp"
    r = run("module", "compare_methods.py", path, "--output-dir", str(out), "--no-render", "--methods", "uniform",
            "--camera", "two_cameras side")
    assert r.returncode == 0, r.stderr
    assert json.loads((out / "comparison.json").read_text())["camera"] == "two_cameras side"

def test_compare_methods_renders_each(blend, tmp_path):
    out = tmp_path / "cmp"
    r = run("module", "compare_methods.py", blend, "--output-dir", str(out), "--longest", "32",
            "--methods", "uniform,psm")
    assert r.returncode == 0, r.stderr
    assert (out / "uniform.png").is_file() and (out / "psm.png").is_file() and (out / "comparison.png").is_file()


BAD = [
    ("render_method.py", ["--method", "nope", "--output", "x.png"], "choose one of"),
    ("render_method.py", ["--output", "x.png", "--size", "100000"], "out of range"),
    ("render_method.py", ["--output", "x.png", "--resolution", "big"], "WxH"),
    ("render_method.py", ["--output", "x.png", "--resolution", "1x1"], "each side must be 4..16384 pixels"),
    ("render_method.py", [], "nothing to write"),
    ("export_animation.py", ["--output", "x.json", "--frames", "5:1"], "START <= END"),
    ("export_animation.py", ["--frames", "1:2"], "--output"),
    ("render_method.py", ["--output", "x.png", "--frame", "99999999999"], "Blender's frames run from -1048574 to"),
    ("export_animation.py", ["--output", "x.json", "--frames", "1048570:1048580"], "Blender's frames run from"),
    ("compare_methods.py", ["--output-dir", "d", "--methods", "uniform,bogus"], "unknown bogus"),
    ("compare_methods.py", ["--output-dir", "d", "--bogus-flag"], "unrecognized arguments"),
    # "" compared (and rendered) every method; a method named twice was computed twice, its second row kept; a
    # view or overlay named twice was drawn and written twice
    ("compare_methods.py", ["--output-dir", "d", "--methods", ""], "unknown (none given)"),
    ("compare_methods.py", ["--output-dir", "d", "--methods", "uniform,psm,uniform"], "uniform given twice"),
    ("overlay_snapshot.py", ["--output-dir", "d", "--views", "camera,camera"], "camera given twice"),
]


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("script,args,message", BAD)
def test_bad_arguments_print_usage_and_fail(mode, blend, tmp_path, script, args, message):
    r = run(mode, script, blend, *args)
    assert r.returncode == 2, (r.returncode, r.stderr)
    assert "usage:" in r.stderr and message in r.stderr


def test_blenders_command_line_without_the_double_dash_says_where_the_arguments_go(blend, tmp_path):
    """``blender -b FILE --python scripts/X.py --output x.png`` (no ``--``): the script sees Blender's own options."""
    argv_setter = BLENDER_MODE.replace('"--python", script, "--"]', '"--python", script]')
    out = tmp_path / "x.png"
    r = subprocess.run([sys.executable, "-c", argv_setter, str(blend), str(SCRIPTS / "render_method.py"),
                        "--output", str(out)], capture_output=True, text=True, timeout=240, cwd=str(ROOT))
    assert r.returncode == 2, r.stderr
    assert "only the arguments after '--': blender -b FILE.blend --python scripts/render_method.py -- " in r.stderr
    assert not out.exists()

def test_missing_blend_file(tmp_path):
    r = run("module", "render_method.py", None, "--output", "x.png")
    assert r.returncode == 2 and "the .blend file is required" in r.stderr
    r = run("module", "render_method.py", tmp_path / "missing.blend", "--output", "x.png")
    assert r.returncode == 2 and "no such .blend file" in r.stderr


@pytest.mark.parametrize("mode", MODES)
def test_scene_problems_are_errors_not_tracebacks(mode, blend, tmp_path):
    r = run(mode, "render_method.py", blend, "--camera", "tiny light", "--json", str(tmp_path / "x.json"))
    assert r.returncode == 1
    assert "lixel: error: object 'tiny light' is a light, not a camera" in r.stderr
    assert "Traceback" not in r.stderr
    r = run(mode, "export_animation.py", blend, "--scene", "nope", "--output", str(tmp_path / "y.json"))
    assert r.returncode == 1 and "there is no scene named 'nope'" in r.stderr
    # --scene "" (an empty shell variable) exported the active scene; --camera "" was refused, as it is now
    r = run(mode, "export_animation.py", blend, "--scene", "", "--output", str(tmp_path / "y.json"))
    assert r.returncode == 1 and "there is no scene named ''" in r.stderr and not (tmp_path / "y.json").exists()


@pytest.mark.parametrize("option,where", [("--json", "missing/x.json"), ("--output", ".")])
def test_an_output_that_cannot_be_written_is_named_not_called_a_bug(blend, tmp_path, option, where):
    path = tmp_path / where
    r = run("module", "render_method.py", blend, option, str(path), "--resolution", "32x18")
    assert r.returncode == 1, r.stderr
    assert f"lixel: error: cannot write '{path}': " in r.stderr and "bug" not in r.stderr, r.stderr


def test_an_exr_picture_holds_the_scene_linear_values_themselves(lixel, tmp_path, load_pixels):
    """``renders.save_image`` to .exr writes the values it is given: Image.save() wrote them sRGB-encoded in 4.2.23
    (0.25 -> 0.537, 2.0 -> 1.353: render_method --output r.exr's ground 2.32 read back 1.44) and changed those
    under alpha < 1 in 5.0.1 (0.25 -> 0.589 at alpha 0.5)."""
    import importlib
    renders = importlib.import_module(lixel.__name__ + ".addon.ui.renders")
    rgba = np.zeros((4, 6, 4), dtype=np.float32)
    rgba[..., 0], rgba[..., 1], rgba[..., 2] = 0.25, 0.5, 2.0
    rgba[..., 3] = np.where(np.arange(6) % 2, 0.5, 1.0)
    renders.save_image(rgba, str(tmp_path / "r.exr"))
    np.testing.assert_array_equal(load_pixels(tmp_path / "r.exr"), rgba)
    assert not [s for s in bpy.data.scenes if s.name.startswith("Lixel")]


def f12_output(scene, tmp_path, picture: str = "f12.exr") -> None:
    """Set ``scene`` to render 96x54 with the Lixel engine into ``tmp_path/picture`` (OpenEXR, or PNG)."""
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage, r.engine = 96, 54, 100, "LIXEL"
    r.image_settings.file_format = "PNG" if picture.endswith(".png") else "OPEN_EXR"
    r.filepath = str(tmp_path / picture)


def f12(scene, tmp_path, name: str, picture: str = "f12.exr") -> Path:
    """Save a copy of the file as ``tmp_path/name`` and render ``scene`` with F12 (:func:`f12_output`); the copy's
    path."""
    f12_output(scene, tmp_path, picture)
    path = tmp_path / name
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    assert bpy.ops.render.render(write_still=True, scene=scene.name) == {"FINISHED"}
    return path


def scripts_picture(path, tmp_path, load_pixels, *args, mode="module", ending="exr") -> np.ndarray:
    """render_method.py's picture of scene "tiny" of ``path`` (with ``args``), run as ``mode`` runs it."""
    out = tmp_path / f"{mode}.{ending}"
    got = run(mode, "render_method.py", path, "--scene", "tiny", "--output", str(out), *args)
    assert got.returncode == 0, got.stderr
    return load_pixels(out)


@pytest.mark.parametrize("hidden", ["from renders", "in the viewport", "by its eye"])
def test_render_method_renders_what_f12_renders(hidden, lixel, tmp_path, load_pixels):
    """A cube hidden from renders (Restrict Render) or hidden in the viewport (its monitor or its eye): the script's
    picture equals F12's (Lixel engine), where it drew what the 3D view shows (the cube hidden from renders and its
    shadow there, the one hidden in the viewport gone)."""
    with active_scene("tiny") as scene:
        cube = scene.objects["tiny cube"]
        if hidden == "from renders":
            cube.hide_render = True
        elif hidden == "in the viewport":
            cube.hide_viewport = True
        else:
            cube.hide_set(True)
        path = f12(scene, tmp_path, "hidden.blend")
    for mode in MODES:
        np.testing.assert_allclose(scripts_picture(path, tmp_path, load_pixels, mode=mode),
                                   load_pixels(tmp_path / "f12.exr"), atol=1e-4)


@pytest.mark.parametrize("mode", MODES)
def test_render_method_renders_a_view_with_nothing_to_shadow_as_f12_does(mode, lixel, tmp_path, load_pixels):
    """The camera turned to the sky (a frame of an animation, say): F12 renders it unshadowed with a warning ("no
    shadows in this view"), where render_method.py refused it ("leave Lixel nothing to shadow", exit 1, no picture).
    The picture equals F12's, with F12's warning; --json is the command line's empty body, and no map is written."""
    with active_scene("tiny") as scene:
        scene.camera.rotation_euler = (3.1, 0.0, 0.0)   # looking up
        path = f12(scene, tmp_path, "sky.blend")
    out = tmp_path / f"{mode}.exr"
    got = run(mode, "render_method.py", path, "--scene", "tiny", "--output", str(out), "--json",
              str(tmp_path / "sky.json"), "--map-output", str(tmp_path / "map.png"))
    assert got.returncode == 0, got.stderr
    assert "lixel: warning: no shadows in this view (the camera sees no shadow receiver" in got.stderr
    assert f"lixel: warning: no shadow map to write to {tmp_path / 'map.png'} (the camera sees no" in got.stderr
    np.testing.assert_allclose(load_pixels(out), load_pixels(tmp_path / "f12.exr"), atol=1e-4)
    doc = json.loads((tmp_path / "sky.json").read_text())
    assert doc["maps"] == [] and doc["diagnostics"]["empty_body"].startswith("the camera sees no shadow receiver")
    assert not (tmp_path / "map.png").exists()


def test_export_animation_reports_a_frame_with_nothing_to_shadow_as_the_command_line_does(lixel, tmp_path):
    """A frame whose camera turns to the sky was recorded as an error ("leave Lixel nothing to shadow ... aim the
    camera"), where F12 renders it and the command line reports an empty body: it is the command line's empty body
    (no maps, diagnostics.empty_body), beside frame 1's maps."""
    with active_scene("tiny") as scene:
        cam = scene.camera
        cam.keyframe_insert("rotation_euler", frame=1)
        cam.rotation_euler = (3.1, 0.0, 0.0)
        cam.keyframe_insert("rotation_euler", frame=2)
        bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "turn.blend"), copy=True)
    out = tmp_path / "turn.json"
    r = run("module", "export_animation.py", tmp_path / "turn.blend", "--scene", "tiny", "--output", str(out),
            "--frames", "1:2", "--method", "uniform")
    assert r.returncode == 0 and "lixel: 2 of 2 frames exported" in r.stdout, r.stdout + r.stderr
    first, second = json.loads(out.read_text())["frames"]
    assert len(first["maps"]) == 1
    assert second["maps"] == [] and second["diagnostics"]["method"] == "uniform"
    assert second["diagnostics"]["empty_body"].startswith("the camera sees no shadow receiver"), second


def test_render_method_writes_no_map_for_a_light_with_shadow_off(blend, lixel, tmp_path):
    """A light with Shadow off draws no shadow map (as in F12): --map-output wrote the 1x1 stand-in the picture is
    drawn with, as if it were the map. It says there is no map, and why."""
    with active_scene("tiny") as scene:
        scene.objects["tiny light"].data.use_shadow = False
        bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "off.blend"), copy=True)
    got = run("module", "render_method.py", tmp_path / "off.blend", "--scene", "tiny", "--output",
              str(tmp_path / "off.png"), "--map-output", str(tmp_path / "map.png"), "--resolution", "32x18")
    assert got.returncode == 0, got.stderr
    assert (f"lixel: warning: no shadow map to write to {tmp_path / 'map.png'} (light 'tiny light' casts no "
            f"shadows") in got.stderr, got.stderr
    assert (tmp_path / "off.png").is_file() and not (tmp_path / "map.png").exists()


def assert_nearly_f12(got: np.ndarray, f12: np.ndarray) -> None:
    """``got`` is F12's picture but for a few shadow-edge pixels (at most 0.1%): F12 fits its maps to what its GPU
    pre-pass sees, the scripts to a ray cast against boxes, and the two differ a little once the scene is not the
    plainest (3 of 5184 pixels with an Array shown alike in the viewport and renders, 2 with a camera shift)."""
    differ = np.abs(got - f12).max(axis=-1) > 1e-4
    assert got.shape == f12.shape and differ.mean() < 1e-3, f"{differ.sum()} of {differ.size} pixels differ from F12's"


def test_render_method_evaluates_modifiers_as_f12_does(lixel, tmp_path, load_pixels):
    """Modifiers evaluate as they render: a Subdivision Surface of Levels Viewport 0 and Render 2, an Array shown
    only in renders and one shown only in the viewport, under Simplify's viewport limit of 0 (render: 6). The
    script's picture equals F12's (Lixel engine; Cycles too evaluates the render settings), where it drew the
    viewport's: the sharp cube, repeated along Y, not the rounded one repeated along X (7.8% of the pixels
    differed)."""
    with active_scene("tiny") as scene:
        cube = scene.objects["tiny cube"]
        subsurf = cube.modifiers.new("render subsurf", "SUBSURF")
        subsurf.levels, subsurf.render_levels = 0, 2
        for name, offset, viewport in (("render array", (1.5, 0, 0), False), ("viewport array", (0, 1.5, 0), True)):
            array = cube.modifiers.new(name, "ARRAY")
            array.relative_offset_displace = offset
            array.show_viewport, array.show_render = viewport, not viewport
        r = scene.render
        r.use_simplify, r.simplify_subdivision, r.simplify_subdivision_render = True, 0, 6
        path = f12(scene, tmp_path, "modifiers.blend")
    for mode in MODES:
        assert_nearly_f12(scripts_picture(path, tmp_path, load_pixels, mode=mode), load_pixels(tmp_path / "f12.exr"))


@pytest.mark.parametrize("light", ["Shadow off", "Shadow Linking", "Light Linking"])
def test_render_method_shadows_the_light_as_f12_does(light, lixel, tmp_path, load_pixels):
    """A sun with Shadow off (Light properties), or whose Shadow Linking or Light Linking leaves the cube out: the
    script's picture equals F12's (Lixel engine, as Cycles: no shadow, no cube's shadow, the cube unlit), where it
    drew the cube's shadow and lit it (29, 29 and 198 of 5184 pixels differed); Shadow off is said."""
    with active_scene("tiny") as scene:
        sun, cube = scene.objects["tiny light"], scene.objects["tiny cube"]
        if light == "Shadow off":
            sun.data.use_shadow = False
        else:
            coll = bpy.data.collections.new("tiny linking")
            coll.objects.link(cube)
            coll.collection_objects[0].light_linking.link_state = "EXCLUDE"
            attr = "blocker_collection" if light == "Shadow Linking" else "receiver_collection"
            setattr(sun.light_linking, attr, coll)
        path = f12(scene, tmp_path, "light.blend")
        if light != "Shadow off":
            bpy.data.collections.remove(coll)
    out = tmp_path / "script.exr"
    got = run("module", "render_method.py", path, "--scene", "tiny", "--output", str(out))
    assert got.returncode == 0, got.stderr
    np.testing.assert_allclose(load_pixels(out), load_pixels(tmp_path / "f12.exr"), atol=1e-4)
    said = "lixel: warning: Light 'tiny light' casts no shadows, as in Blender's engines: its Shadow is off"
    assert (said in got.stderr) == (light == "Shadow off"), got.stderr


@pytest.mark.parametrize("crop", [False, True])
def test_render_method_keeps_the_render_region_as_f12_does(crop, lixel, tmp_path, load_pixels):
    """A Render Region (Output properties > Format) over the middle half, with and without Crop to Render Region:
    the script's picture equals F12's (as Cycles: the whole frame, transparent black outside the region; the region
    alone with Crop), where it drew the whole frame (2592 of 5184 pixels differed; 96x54 against F12's 48x54)."""
    with active_scene("tiny") as scene:
        r = scene.render
        r.use_border, r.use_crop_to_border = True, crop
        r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = 0.25, 0.75, 0.1, 0.8
        path = f12(scene, tmp_path, "region.blend")
    np.testing.assert_allclose(scripts_picture(path, tmp_path, load_pixels), load_pixels(tmp_path / "f12.exr"),
                               atol=1e-4)


def test_a_camera_or_light_of_another_scene(lixel, tmp_path, load_pixels):
    """``--camera`` naming a camera that lives in another scene (or an excluded collection): the script renders
    through it as F12 does with it as the scene camera (Blender evaluates the scene camera wherever it lives), where
    it read the matrix the file stored, never evaluated (the world origin: "the camera sees no shadow receiver").
    ``--light`` naming another scene's light: refused by name, as the panel's Lixel light is (Cycles lights nothing
    with it), where the script rendered the scene lit by it."""
    with active_scene("tiny") as scene:
        other = bpy.data.scenes.new("tiny other")
        side = bpy.data.objects.new("side camera", scene.camera.data)
        side.location, side.rotation_euler = (-6.0, -7.0, 5.0), (1.0, 0.0, -0.7)
        spot = bpy.data.objects.new("other light", bpy.data.lights.new("other light", "SPOT"))
        for ob in (side, spot):
            other.collection.objects.link(ob)
        f12_output(scene, tmp_path)
        try:
            bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "other.blend"), copy=True)
            scene.camera = side       # for F12 alone: the file keeps its own camera
            assert bpy.ops.render.render(write_still=True, scene=scene.name) == {"FINISHED"}
        finally:
            bpy.data.scenes.remove(other)
            for ob in (side, spot):
                bpy.data.objects.remove(ob)
    path = tmp_path / "other.blend"
    assert_nearly_f12(scripts_picture(path, tmp_path, load_pixels, "--camera", "side camera"),
                      load_pixels(tmp_path / "f12.exr"))
    got = run("module", "render_method.py", path, "--scene", "tiny", "--light", "other light", "--output",
              str(tmp_path / "lit.exr"))
    assert got.returncode == 1 and "Traceback" not in got.stderr
    assert ("lixel: error: The Lixel light 'other light' is not among the lights scene 'tiny' shows (hidden, in an "
            "excluded collection or in another scene)") in got.stderr, got.stderr


def test_export_animation_follows_render_visibility_keyframed_over_the_frames(lixel, tmp_path):
    """A tall box keyframed out of renders (Restrict Render) at frame 3: exporting frames 1 to 3 gives frame 3 the
    matrices of frame 3 alone (as F12 renders each frame with that frame's visibility), where the first frame's
    visibility held for all and frame 3's maps were those of a scene still showing the box."""
    path = tmp_path / "keyed.blend"
    with active_scene("tiny") as scene:
        cube = scene.objects["tiny cube"]
        tall = bpy.data.objects.new("tiny tall", cube.data)
        scene.collection.objects.link(tall)
        tall.location, tall.scale = (-3.0, 2.0, 1.0), (1.0, 1.0, 4.0)
        for frame, hidden in ((1, False), (3, True)):
            tall.hide_render = hidden
            tall.keyframe_insert("hide_render", frame=frame)
        scene.frame_set(1)
        try:
            bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
        finally:
            bpy.data.objects.remove(tall)
    frames = {}
    for span in ("1:3", "3:3"):
        out = tmp_path / f"{span.replace(':', '-')}.json"
        got = run("module", "export_animation.py", path, "--scene", "tiny", "--frames", span, "--output", str(out))
        assert got.returncode == 0, got.stderr
        frames[span] = {f["frame"]: f for f in json.loads(out.read_text())["frames"]}
    assert frames["1:3"][3] == frames["3:3"][3]
    assert frames["1:3"][1]["maps"] != frames["1:3"][3]["maps"]


def _is_viewport_group():
    """A Geometry Nodes group that passes its geometry on in renders and drops it in the viewport (Is Viewport)."""
    tree = bpy.data.node_groups.new("lixel_test is viewport", "GeometryNodeTree")
    for way in ("INPUT", "OUTPUT"):
        tree.interface.new_socket("Geometry", in_out=way, socket_type="NodeSocketGeometry")
    given, out = tree.nodes.new("NodeGroupInput"), tree.nodes.new("NodeGroupOutput")
    asks, switch = tree.nodes.new("GeometryNodeIsViewport"), tree.nodes.new("GeometryNodeSwitch")
    switch.input_type = "GEOMETRY"
    tree.links.new(asks.outputs[0], switch.inputs[0])
    tree.links.new(given.outputs[0], switch.inputs[1])     # False (a render): the geometry
    tree.links.new(switch.outputs[0], out.inputs[0])
    return tree


@pytest.mark.parametrize("how", ["Dots", "emitter off in renders"])
def test_particles_as_f12_renders_them_and_is_viewport(how, lixel, tmp_path, load_pixels):
    """A particle system instancing the cube over the ground, shown as Dots in the viewport (Viewport Display >
    Display As), or with its emitter shown in the viewport only (Instancing > Show Instancer: Render off): the
    script's picture equals F12's, where it left the 30 instanced cubes out (127 of 5184 pixels differed) or drew
    the ground F12 leaves out (3684). Geometry Nodes asking Is Viewport cannot be evaluated as renders by a script:
    said by name."""
    with active_scene("tiny") as scene:
        cube, ground = scene.objects["tiny cube"], scene.objects["tiny ground"]
        system = ground.modifiers.new("lixel_test particles", "PARTICLE_SYSTEM").particle_system.settings
        system.count, system.frame_start, system.frame_end, system.physics_type = 30, 1, 1, "NO"
        system.render_type, system.instance_object, system.particle_size = "OBJECT", cube, 0.3
        if how == "Dots":
            system.display_method = "DOT"
        else:
            ground.show_instancer_for_render = False
        path = f12(scene, tmp_path, "particles.blend")
        ground.modifiers.new("lixel_test nodes", "NODES").node_group = tree = _is_viewport_group()
        bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "nodes.blend"), copy=True)
        bpy.data.particles.remove(system)
        bpy.data.node_groups.remove(tree)
    out = tmp_path / "script.exr"
    got = run("module", "render_method.py", path, "--scene", "tiny", "--output", str(out))
    assert got.returncode == 0 and "Is Viewport" not in got.stderr, got.stderr
    assert_nearly_f12(load_pixels(out), load_pixels(tmp_path / "f12.exr"))
    if how == "Dots":
        got = run("module", "render_method.py", tmp_path / "nodes.blend", "--scene", "tiny", "--output", str(out))
        assert got.returncode == 0, got.stderr
        assert ("lixel: warning: object 'tiny ground' has Geometry Nodes that ask Is Viewport: a script evaluates "
                "them as the 3D view does, F12 and Cycles as renders; render with F12 (the Lixel engine) for the "
                "render's answer") in got.stderr


def test_render_method_keeps_a_transparent_film_as_f12_does(lixel, tmp_path, load_pixels):
    """Film Transparent (Render properties > Film): the script's picture equals F12's, (0, 0, 0, 0) where no surface
    is (as Cycles), where it drew the world's colour there, opaque (969 of 5184 pixels differed)."""
    with active_scene("tiny") as scene:
        scene.render.film_transparent = True
        path = f12(scene, tmp_path, "film.blend")
    rendered = load_pixels(tmp_path / "f12.exr")
    assert (rendered[..., 3] == 0).mean() > 0.1
    np.testing.assert_allclose(scripts_picture(path, tmp_path, load_pixels), rendered, atol=1e-4)


def test_a_view_layer_with_surfaces_off_is_refused_by_name(lixel, tmp_path):
    """View Layer properties > Filter > Surfaces off: F12 and Cycles show the world alone. The script drew every
    surface and its shadow (4066 of 5184 pixels differed from F12's); it now says why it has nothing to draw."""
    path = tmp_path / "filtered.blend"
    with active_scene("tiny") as scene:
        layer = scene.view_layers[0]
        layer.use_solid, name = False, layer.name
        bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    got = run("module", "render_method.py", path, "--scene", "tiny", "--output", str(tmp_path / "out.exr"))
    assert got.returncode == 1 and not (tmp_path / "out.exr").exists()
    assert (f"lixel: error: view layer '{name}' has Surfaces off (View Layer "
            f"properties > Filter), so as in Cycles its renders show only the world background: switch Surfaces on"
            ) in got.stderr, got.stderr


def test_a_picture_is_saved_through_the_scenes_color_management_as_f12_saves_it(lixel, tmp_path, load_pixels):
    """A PNG of the shaded picture goes through the scene's Color Management (here AgX, Exposure 0.5), as F12 saves
    it, where the script wrote it sRGB-encoded whatever the view (4066 of 5184 pixels differed by more than 3/255
    under a new scene's AgX in 5.0.1, Filmic in 4.2.23). Dither is off: F12 adds noise."""
    with active_scene("tiny") as scene:
        scene.view_settings.view_transform, scene.view_settings.exposure = "AgX", 0.5
        scene.render.dither_intensity = 0.0
        path = f12(scene, tmp_path, "managed.blend", picture="f12.png")
    got = scripts_picture(path, tmp_path, load_pixels, ending="png")
    np.testing.assert_allclose(got, load_pixels(tmp_path / "f12.png"), atol=1.5 / 255)
