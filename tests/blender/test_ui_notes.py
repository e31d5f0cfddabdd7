"""What F12 warns about, the sidebar says too: the scene's notes (``addon.scene.notes.scene_notes``: a second light
Lixel does not render, a Shadow Catcher, a textured world, ...) are gathered by one function for the render's
warnings and the live state, and the panel draws them in full, each naming the object and what to do. Before, the
panel showed only the light's notes: a user in the viewport never learnt that their second light lit nothing or
their sky was replaced by a constant. They are gathered when the live state is updated, never per redraw."""
import importlib

import bpy
import numpy as np
import pytest

from test_render_engine import _render, add, build, scene  # noqa: F401
from test_ui_panel import StandInLayout, panel  # noqa: F401
from worlds import background, sky_world


@pytest.fixture(scope="module")
def live(lixel):
    return importlib.import_module(f"{lixel.__name__}.addon.ui.live")


class IconLayout(StandInLayout):
    """A stand-in layout that records each label's icon too, as ("label", text, icon)."""

    def _child(self, *args, **kw):
        return IconLayout(self.log)

    row = column = box = split = column_flow = grid_flow = _child

    def label(self, text="", icon="NONE", **kw):
        assert isinstance(text, str)
        self.log.append(("label", text, icon))


def main_panel_labels(panel) -> list:  # noqa: F811
    log = []
    fake = type("Fake", (), {})()
    fake.layout = IconLayout(log)
    panel.LIXEL_PT_main.draw(fake, bpy.context)
    return [entry[1:] for entry in log if entry[0] == "label"]


def shown_in_full(labels, note: str) -> bool:
    """Whether ``note`` is drawn whole: a run of labels, the first behind the alert icon, that joins to it."""
    texts = [t for t, _ in labels]
    for i, (text, icon) in enumerate(labels):
        if icon == "ERROR" and text and note.startswith(text):
            j = i + 1
            while len(" ".join(texts[i:j])) < len(note) and j < len(texts):
                j += 1
            if " ".join(texts[i:j]) == note:
                return True
    return False


def _second_light(scene):
    point = add(scene, "Point", bpy.data.lights.new("Point", "POINT"))
    point.data.energy, point.location = 1000.0, (0.0, 0.0, 5.0)


def _shadow_catcher(scene):
    scene.objects["Ground"].is_shadow_catcher = True


def _textured_world(scene):
    scene.world = sky_world("lixel_test sky", (0.2, 0.3, 0.4))
    sky = scene.world.node_tree.nodes.new("ShaderNodeTexSky")
    scene.world.node_tree.links.new(sky.outputs[0], background(scene.world).inputs["Color"])


def _depth_of_field(scene):
    scene.camera.data.dof.use_dof = True     # Cycles and EEVEE blur out of focus (F-Stop 2.8); Lixel said nothing


CASES = {
    "second light": (_second_light, "light 'Point' lights nothing here", "choose the light Lixel renders"),
    "shadow catcher": (_shadow_catcher, "object 'Ground' is a Shadow Catcher", "switch it off"),
    "textured world": (_textured_world, "World 'lixel_test sky' lights with its Sky Texture node",
                       "set World properties > Viewport Display > Color"),
    "depth of field": (_depth_of_field, "Camera 'Cam' has Depth of Field on: Lixel renders every distance in focus",
                       "switch it off in Camera properties > Depth of Field"),
}


@pytest.fixture
def worlds_removed(scene):
    yield
    world, scene.world = scene.world, None
    if world is not None:
        bpy.data.worlds.remove(world)


@pytest.mark.parametrize("case", list(CASES))
def test_the_panel_says_what_the_render_warns_about(engine, live, panel, scene, worlds_removed, case):  # noqa: F811
    make, names, remedy = CASES[case]
    build(scene)
    make(scene)
    assert bpy.ops.lixel.refresh() == {"FINISHED"}
    notes = live.state(scene).notes
    assert len(notes) == 1 and names in notes[0] and remedy in notes[0]
    assert tuple(f"Lixel: {n}" for n in notes) == _render(engine, scene)["warnings"]      # the same text as F12's
    labels = main_panel_labels(panel)
    assert shown_in_full(labels, notes[0])
    assert max(len(t) for t, _ in labels) <= panel.LINE_CHARS


def test_a_clean_scene_has_no_notes(engine, live, panel, scene):  # noqa: F811
    build(scene)
    assert bpy.ops.lixel.refresh() == {"FINISHED"}
    assert live.state(scene).notes == ()
    assert _render(engine, scene)["warnings"] == ()
    assert not any(icon == "ERROR" for _, icon in main_panel_labels(panel))


def test_notes_follow_the_live_updates_and_not_the_redraws(live, panel, scene, worlds_removed, monkeypatch):  # noqa: F811
    """A world edited after the Refresh (its nodes, then its viewport colour: each comes with a ShaderNodeTree
    update, which the depsgraph handler passes on): the live update gathers the notes again; drawing the panel,
    however often, gathers nothing."""
    build(scene)
    scene.world = sky_world("lixel_test sky", (0.2, 0.3, 0.4))
    assert bpy.ops.lixel.refresh() == {"FINISHED"}
    assert live.state(scene).notes == ()
    gathered = []
    real = live.scene_notes
    monkeypatch.setattr(live, "scene_notes", lambda *a, **kw: gathered.append(1) or real(*a, **kw))
    for _ in range(3):
        main_panel_labels(panel)
    assert gathered == []
    sky = scene.world.node_tree.nodes.new("ShaderNodeTexSky")
    scene.world.node_tree.links.new(sky.outputs[0], background(scene.world).inputs["Color"])
    bpy.context.view_layer.update()     # runs depsgraph_update_post, as an edit in the UI does
    assert len(gathered) == 1
    notes = live.state(scene).notes
    assert len(notes) == 1 and notes[0].startswith("World 'lixel_test sky' lights with its Sky Texture node")
    for _ in range(3):
        assert shown_in_full(main_panel_labels(panel), notes[0])
    assert len(gathered) == 1
    scene.world.color = (0.5, 0.25, 0.125)    # the viewport colour Lixel lights with instead: only the World changes
    bpy.context.view_layer.update()
    assert len(gathered) == 2 and "viewport colour (0.5, 0.25, 0.125)" in live.state(scene).notes[0]


def test_a_light_with_shadow_off_is_said_and_pictured_unshadowed(live, panel, scene, lixel):  # noqa: F811
    """Light properties > Shadow off after a Refresh (the depsgraph handler's update, as an edit in the UI): the
    sidebar says the light casts no shadows and the 3D view's picture of the camera view is unshadowed, as F12
    renders it (``test_render_engine``); the map picture is left out. Before, the state kept its note (none) and its
    picture, and the picture showed the shadows; switched on again, both come back."""
    renders = importlib.import_module(f"{lixel.__name__}.addon.ui.renders")
    build(scene)
    sun = scene.objects["Sun"]
    assert bpy.ops.lixel.refresh() == {"FINISHED"}

    def picture():
        st = live.state(scene)
        return st, renders.pip_images(st, bpy.context.evaluated_depsgraph_get(), 48, True, True)
    on, shadowed = picture()
    generation = on.generation
    said = "Light 'Sun' casts no shadows, as in Blender's engines: its Shadow is off (Light properties > Shadow)"
    assert said not in on.note and set(shadowed) == {"scene", "map"}
    sun.data.use_shadow = False
    bpy.context.view_layer.update()
    off, unshadowed = picture()
    assert said in off.note and off.generation > generation    # the 3D view's cached pictures are drawn again
    assert set(unshadowed) == {"scene"} and (unshadowed["scene"][..., :3] >= shadowed["scene"][..., :3] - 1e-6).all()
    assert (unshadowed["scene"][..., :3] > shadowed["scene"][..., :3] + 0.1).any()
    labels = [t for t, _ in main_panel_labels(panel)]
    assert said.split()[0] in " ".join(labels) and "Shadow is off" in " ".join(labels)
    sun.data.use_shadow = True
    bpy.context.view_layer.update()
    again, reshadowed = picture()
    assert said not in again.note
    np.testing.assert_array_equal(reshadowed["scene"], shadowed["scene"])
