"""Scene properties > Units: Lixel computes in Blender units, so a Unit Scale changes no result, and the lengths the
Readouts panel shows (the focus's depth range, a cascade's split depths) are Blender's, in the scene's unit system
(a Unit Scale of 0.01 shows 100 units as 1 m). The panel printed the units as metres ("0.1–25 m" where Blender's own
fields read 1 mm to 25 cm)."""
import importlib
import re

import bpy
import numpy as np
import pytest

from ui_scenes import active_scene


@pytest.fixture(scope="module")
def live(lixel):
    return importlib.import_module(f"{lixel.__name__}.addon.ui.live")


def _lengths(text: str, system: str, scale: float) -> list:
    """The lengths in a readout (``a–b`` ranges), in Blender units."""
    shown = re.search(r"([^,–]+)–([^,]+)", text.split("depth ")[-1])
    return [bpy.utils.units.to_value(system, "LENGTH", s.strip()) / scale for s in shown.groups()]


@pytest.mark.parametrize("system, scale", [("METRIC", 1.0), ("METRIC", 0.01), ("IMPERIAL", 1.0),
                                           ("METRIC", 1000.0)])
def test_readouts_show_lengths_in_the_scenes_units_and_results_do_not_change(live, system, scale):
    with active_scene("lixel_units") as scene:
        scene.lixel.method = "cascade"
        assert bpy.ops.lixel.refresh() == {"FINISHED"}
        st = live.state(scene)
        before = [m.matrix.copy() for m in st.setup.maps]
        scene.unit_settings.system, scene.unit_settings.scale_length = system, scale
        assert bpy.ops.lixel.refresh() == {"FINISHED"}
        st = live.state(scene)
        assert all(np.array_equal(a, m.matrix) for a, m in zip(before, st.setup.maps, strict=True))
        rows = dict(live.readouts(st))
        z = st.setup.diagnostics.extra["splits"]
        splits = [label for label in rows if label.startswith("Split ")]
        assert len(splits) == len(z) - 1 >= 2
        for i, label in enumerate(splits):
            np.testing.assert_allclose(_lengths(rows[label], system, scale), z[i:i + 2], rtol=6e-3)
        np.testing.assert_allclose(_lengths(rows["Focus"], system, scale), st.body.visible.depth_range, rtol=6e-3)
