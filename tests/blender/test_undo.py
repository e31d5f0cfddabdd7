"""Ctrl+Z after each Lixel operator gives the user's file back as it was, and Ctrl+Shift+Z gives the operator's work
back, as the operators' ``{'REGISTER', 'UNDO'}`` promise.

Undo works headless: an operator called as the UI calls it (``bpy.ops.lixel.X('EXEC_DEFAULT', True)``: the second
argument pushes its undo step) and ``bpy.ops.ed.undo``/``redo`` (4.2 and 5.0). An undo step reloads every
datablock, which leaves the Python references of a test session dangling, so the steps run in a process of their
own; it prints, per operator, what changed and whether undo and redo gave back each state (every datablock's
``ui_scenes.digest`` and the scene's Lixel settings)."""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent

CHILD = r"""
import json, sys
sys.path.insert(0, sys.argv[1])
import bpy
import conftest
from ui_scenes import build, digest
conftest.enable_lixel()
scene = bpy.context.scene
bpy.data.batch_remove(list(scene.objects))
bpy.data.orphans_purge(do_recursive=True)     # the start-up file's cube, camera and light data
build(scene)
bpy.context.view_layer.update()

def state():
    sc = bpy.context.scene
    props = sc.lixel
    data = {f"{kind}:{idb.name}": digest(idb) for kind in ("objects", "meshes", "collections", "node_groups",
                                                           "materials", "texts", "images")
            for idb in getattr(bpy.data, kind)}
    data["settings"] = repr([(k, repr(getattr(props, k))) for k in props.bl_rna.properties.keys() if k != "rna_type"])
    data["planes"] = repr([(tuple(p.point), tuple(p.normal)) for p in props.planes])
    return data

def select(names):
    for ob in bpy.context.scene.objects:
        ob.select_set(ob.name in names)
    bpy.context.view_layer.objects.active = bpy.context.scene.objects[names[0]]

bpy.ops.ed.undo_push(message="before Lixel")
out = {}
for name, kw, selected in json.loads(sys.argv[2]):
    if selected:
        select(selected)
    before = state()
    result = getattr(bpy.ops.lixel, name)("EXEC_DEFAULT", True, **kw)
    after = state()
    bpy.ops.ed.undo()
    undone = state()
    bpy.ops.ed.redo()
    redone = state()
    out[name] = {"result": sorted(result), "changed": sorted(k for k in after if before.get(k) != after[k]),
                 "undo": sorted(k for k in before.keys() | undone.keys() if before.get(k) != undone.get(k)),
                 "redo": sorted(k for k in after.keys() | redone.keys() if after.get(k) != redone.get(k))}
saved = state()
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[3])
bpy.ops.wm.open_mainfile(filepath=sys.argv[3])
reopened = state()
out["reopened"] = sorted(k for k in saved.keys() | reopened.keys() if saved.get(k) != reopened.get(k))
conftest.disable_lixel()
print("RESULT " + json.dumps(out))
"""

OPERATORS = [  # (operator, arguments, objects selected first), in an order where each finds what it needs
    ("refresh", {}, None),
    ("toggle_overlay", {"overlay": "show_body"}, None),
    ("bake_debug", {}, None),
    ("frustum_add", {}, None),
    ("sync_matrices", {}, None),
    ("texel_grid_add", {}, ["Scene ground"]),
    ("planes_from_selection", {}, ["Scene ground"]),
    ("plane_remove", {"index": 0}, None),
    ("reset_settings", {}, None),
    ("compare", {}, None),
    ("overlay_snapshot", {"width": 64}, None),
]
"""Every operator that changes data (test_operators.CHANGES_DATA), export_json aside: it writes a file, which
undo does not take back."""


@pytest.fixture(scope="module")
def steps(lixel, tmp_path_factory):
    folder = tmp_path_factory.mktemp("undo")
    ops = [(n, dict(kw, directory=str(folder)) if n == "overlay_snapshot" else kw, sel) for n, kw, sel in OPERATORS]
    env = dict(os.environ, XDG_CACHE_HOME=str(folder / "xdg"), BLENDER_USER_RESOURCES=str(folder / "user"))
    r = subprocess.run([sys.executable, "-c", CHILD, str(HERE), json.dumps(ops), str(folder / "saved.blend")],
                       capture_output=True, text=True,
                       timeout=300, env=env, cwd=str(folder))
    line = next((s for s in r.stdout.splitlines() if s.startswith("RESULT ")), None)
    assert r.returncode == 0 and line, r.stdout[-2000:] + r.stderr[-3000:]
    return json.loads(line[len("RESULT "):])


def test_the_steps_cover_every_operator_that_changes_data(lixel):
    from test_operators import CHANGES_DATA
    assert sorted({n for n, *_ in OPERATORS} | {"export_json"}) == sorted(CHANGES_DATA)


@pytest.mark.parametrize("name", [n for n, *_ in OPERATORS])
def test_undo_gives_the_file_back_and_redo_the_operators_work(steps, name):
    step = steps[name]
    assert step["result"] == ["FINISHED"]
    assert step["undo"] == [], f"undo left {step['undo']} changed"
    assert step["redo"] == [], f"redo did not restore {step['redo']}"


def test_what_the_operators_made_is_in_the_saved_file(steps):
    """Saved and opened again, the file holds what the operators made: the comparison's picture too, which the
    comparison text names (a generated image's pixels live only in memory, and an image nobody uses is not saved)."""
    assert steps["reopened"] == []


def test_the_operators_that_add_things_did_change_the_file(steps):
    """So that an undo that restores nothing cannot pass unnoticed: these steps changed something to undo."""
    for name in ("bake_debug", "frustum_add", "texel_grid_add", "planes_from_selection", "compare", "toggle_overlay"):
        assert steps[name]["changed"], name
