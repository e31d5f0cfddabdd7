"""The comparison mosaic (scripts/compare_methods.py, the compare operator)
labels every tile: a strip of text drawn with blf off-screen above each picture."""
import importlib

import bpy
import numpy as np
import pytest


@pytest.fixture(scope="module")
def renders(lixel):
    importlib.import_module(f"{lixel.__name__}.addon.gpu.context").ensure_gpu_context()
    return importlib.import_module(f"{lixel.__name__}.addon.ui.renders")


def test_label_strip_draws_its_text(renders):
    strip = renders.label_strip(["lispsm: 1 map(s)", "θ 45.0°"], 160)
    assert strip.shape == (2 * renders.LABEL_LINE + 6, 160, 4)
    text = strip[..., 0] > 0.5
    assert 50 < text.sum() < 0.5 * text.size          # white glyphs on the dark strip
    top, bottom = text[strip.shape[0] // 2:], text[:strip.shape[0] // 2]   # row 0 is the bottom
    assert top.any() and bottom.any()                  # both lines drawn
    assert renders.label_strip([""], 40)[..., :3].max() < 0.2


def test_every_tile_of_the_mosaic_has_its_own_label(renders):
    tiles = [np.full((20, 60, 4), v, dtype=np.float32) for v in (0.3, 0.6)]
    plain = renders.mosaic(tiles, columns=2)
    labelled = renders.mosaic(tiles, columns=2, labels=[["uniform"], ["lispsm, a longer label"]])
    strip_h = renders.LABEL_LINE + 6
    assert labelled.shape[0] == plain.shape[0] + strip_h
    left, right = labelled[20:, :60, 0] > 0.5, labelled[20:, 64:, 0] > 0.5
    assert left.any() and right.any() and right.sum() > left.sum()
    np.testing.assert_allclose(labelled[:20, :60], tiles[0])   # the picture itself is untouched


def test_method_label_names_the_warp_parameter(renders):
    row = {"method": "lispsm", "theta": np.radians(45.0), "n_opt": 3.25, "lam": None, "maps": 1,
           "footprint_median_px": 1.2, "footprint_max_px": 8.0, "fallbacks": []}
    first, second = renders.method_label(row, bpy.data.scenes[0], 12.0)
    assert first == "lispsm: 1 map(s), 12 ms"
    assert second == "θ 45.0°, n_opt 3.25 m, texel footprint 1.2 px (max 8)"
