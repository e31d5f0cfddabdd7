"""The sidebar's draw code runs for every method's parameters (and every light
type, computed or not, with an error), drawing only properties and operators
that exist."""
import importlib

import bpy
import pytest

from ui_scenes import active_scene


class StandInLayout:
    """Records what draw code asks for; every container returns another stand-in.
    ``prop`` checks the property exists, ``operator`` that the operator exists."""

    def __init__(self, log):
        self.log = log
        self.enabled = True
        self.use_property_split = False
        self.use_property_decorate = True
        self.active = True
        self.alert = False
        self.scale_y = 1.0

    def _child(self, *args, **kw):
        return StandInLayout(self.log)

    row = column = box = split = column_flow = grid_flow = _child

    def separator(self, *args, **kw):
        pass

    def label(self, text="", **kw):
        assert isinstance(text, str)
        self.log.append(("label", text))

    def prop(self, data, name, **kw):
        assert name in data.bl_rna.properties.keys(), f"{type(data).__name__} has no property {name!r}"
        self.log.append(("prop", name))

    def operator(self, idname, **kw):
        group, name = idname.split(".")
        op = getattr(getattr(bpy.ops, group), name)
        props = op.get_rna_type()
        self.log.append(("operator", idname))

        class Props:
            def __setattr__(self, key, value):
                assert key in props.properties.keys(), f"{idname} has no property {key!r}"
                object.__setattr__(self, key, value)
        return Props()


@pytest.fixture(scope="module")
def panel(lixel):
    return importlib.import_module(f"{lixel.__name__}.addon.ui.panel")


@pytest.fixture(scope="module")
def properties(lixel):
    return importlib.import_module(f"{lixel.__name__}.addon.ui.properties")


def draw_all(panel, context):
    log = []
    for cls in panel.classes:
        assert cls.poll(context)
        fake = type("Fake", (), {})()
        fake.layout = StandInLayout(log)
        cls.draw(fake, context)
    return log


@pytest.mark.parametrize("light_type", ["SUN", "POINT", "SPOT"])
def test_panel_draws_every_method(lixel, panel, properties, light_type):
    live = importlib.import_module(f"{lixel.__name__}.addon.ui.live")
    with active_scene(f"lixel_panel_{light_type.lower()}", light=light_type) as scene:
        scene.lixel.light = scene.objects[f"{scene.name} light"]
        for method in properties.available_methods():
            scene.lixel.method = method
            for computed in (False, True):
                if computed:
                    try:
                        bpy.ops.lixel.refresh()
                    except RuntimeError:  # a method the core rejects here: the panel shows the error
                        pass
                log = draw_all(panel, bpy.context)
                props = {n for kind, n in log if kind == "prop"}
                ops = {n for kind, n in log if kind == "operator"}
                assert {"light", "method", "shadow_map_size", "bias_mode", "pcf_kernel", "mdsm_depths",
                        "eye_blur"} <= props
                assert {"lixel.refresh", "lixel.toggle_overlay", "lixel.bake_debug", "lixel.export_json",
                        "lixel.compare"} <= ops
                assert set(panel.method_parameters(method, light_type)) <= props
                if method in properties.LAMBDA_METHODS:
                    assert {"use_lambda", "lam"} <= props
                if method in properties.N_OPT_METHODS:
                    assert {"delta_z", "middle_vector"} <= props
                if method in properties.PLANE_METHODS:
                    assert "lixel.planes_from_selection" in ops
                labels = [t for kind, t in log if kind == "label"]
                st = live.state(scene)
                if computed and st.ok:
                    assert "B vertices" in labels and "θ" in labels and "Texel footprint" in labels
                elif computed:
                    assert "Error" in labels and st.error.split()[0] in " ".join(labels)


def test_panel_shows_the_error_of_a_scene_without_camera(lixel, panel):
    with active_scene("lixel_panel_nocam", camera=False):
        with pytest.raises(RuntimeError):
            bpy.ops.lixel.refresh()
        labels = [t for kind, t in draw_all(panel, bpy.context) if kind == "label"]
        assert any("no camera" in t for t in labels)


SIDEBAR_CHARS = 42
"""Characters of a label the sidebar shows whole at its default width."""


def test_a_warning_too_long_for_one_line_is_shown_in_full(lixel, panel):
    """An area light's note is a sentence: Blender cuts a label off at the sidebar's edge, so the panel wraps it
    into lines that fit, as it wraps an error."""
    live = importlib.import_module(f"{lixel.__name__}.addon.ui.live")
    with active_scene("lixel_panel_note", light="AREA") as scene:
        bpy.ops.lixel.refresh()
        note = " ".join(live.state(scene).note.split())
        assert note.startswith("Area light") and len(note) > SIDEBAR_CHARS
        labels = [t for kind, t in draw_all(panel, bpy.context) if kind == "label"]
        first = next(i for i, t in enumerate(labels) if t and note.startswith(t))
        shown = labels[first:first + 1]
        while len(" ".join(shown)) < len(note):
            shown.append(labels[first + len(shown)])
        assert " ".join(shown) == note
        assert max(len(t) for t in shown) <= SIDEBAR_CHARS


def test_a_readout_that_is_a_sentence_is_shown_in_full(lixel, panel):
    """The Readouts panel repeats an error (and a fallback's reason) as a value: wrapped to the sidebar too."""
    live = importlib.import_module(f"{lixel.__name__}.addon.ui.live")
    with active_scene("lixel_panel_readouts") as scene:
        scene.camera.rotation_euler = (3.14159, 0.0, 0.0)      # looking at the sky: an error
        with pytest.raises(RuntimeError):
            bpy.ops.lixel.refresh()
        error = " ".join(live.state(scene).error.split())
        log = []
        fake = type("Fake", (), {})()
        fake.layout = StandInLayout(log)
        panel.LIXEL_PT_readouts.draw(fake, bpy.context)
        labels = [t for kind, t in log if kind == "label" and t]
        assert error in " ".join(labels)
        assert max(len(t) for t in labels) <= SIDEBAR_CHARS
