"""A light's emitter size where it is zero or scaled, as Cycles renders it (measured in 4.2.23 and 5.0.1, a ground
lit from 2 m, the picture's mean):

* an area light of Size 0 (or Size Y 0 for a rectangle or ellipse, or an X or Y scale of 0) emits nothing, with
  Normalize on or off (mean 9.5e-9 against 0.081 at Size 0.5): Lixel lit the frame with it as with any spot;
* with Normalize off (5.0), a Radius 0 point or spot light is 4 times as bright as with it on (not 4 pi r^2 = 0 times:
  Lixel's frame went black), a sun of Angle 0 as bright (not pi sin^2 0 = 0 times: black), and an area light's area
  is scaled by its object's X and Y scale (Size 0.5 at scale (2, 2, 1): 0.080 against 0.020 at scale 1; Lixel read
  the Size alone, 4 times too dark).
"""
import bpy
import numpy as np
import pytest

from test_render_engine import _render, build, scene  # noqa: F401

HAS_NORMALIZE = "normalize" in bpy.types.Light.bl_rna.properties


def combined(engine, scene) -> np.ndarray:  # noqa: F811
    return np.array(_render(engine, scene)["result"].combined, dtype=np.float32)


def _as(scene, kind):  # noqa: F811
    build(scene)
    ob = scene.objects["Sun"]
    ob.location = (1.0, -2.0, 5.0)
    ob.data.type = kind
    ob.data.energy = 3.0 if kind == "SUN" else 300.0
    return ob


@pytest.mark.parametrize("zero", ["size", "size_y", "scale_x", "scale_y"])
def test_an_area_light_of_no_size_lights_nothing_and_is_named(engine, scene, zero):  # noqa: F811
    ob = _as(scene, "AREA")
    ob.data.shape, ob.data.size, ob.data.size_y = "RECTANGLE", 1.0, 0.5
    lit = combined(engine, scene)
    ob.data.energy = 0.0
    dark = combined(engine, scene)
    assert not np.allclose(lit, dark, atol=0.05)
    ob.data.energy = 300.0
    if zero.startswith("scale"):
        ob.scale["xy".index(zero[-1])] = 0.0
    else:
        setattr(ob.data, zero, 0.0)
    got = _render(engine, scene)
    np.testing.assert_allclose(np.array(got["result"].combined, dtype=np.float32), dark, atol=1e-6)
    assert any("Area light 'Sun' has no area" in w and "emits nothing" in w and "Light properties" in w
               for w in got["warnings"]), got["warnings"]


@pytest.mark.skipif(not HAS_NORMALIZE, reason="Blender 4.2 has no light Normalize")
@pytest.mark.parametrize("kind, shape, scale, factor",
                         [("POINT", dict(shadow_soft_size=0.0), (1, 1, 1), 4.0),
                          ("SPOT", dict(shadow_soft_size=0.0), (1, 1, 1), 4.0),
                          ("SUN", dict(angle=0.0), (1, 1, 1), 1.0),
                          ("AREA", dict(shape="SQUARE", size=0.5), (2, 2, 1), 4 * 0.25),
                          ("AREA", dict(shape="DISK", size=1.0), (3, 0.5, 1), 1.5 * np.pi / 4)])
def test_normalize_off_at_zero_size_or_scaled_lights_as_in_cycles(engine, scene, kind, shape, scale,
                                                                  factor):  # noqa: F811
    ob = _as(scene, kind)
    ob.scale = scale
    for name, value in shape.items():
        setattr(ob.data, name, value)
    ob.data.normalize = False
    unnormalized = combined(engine, scene)
    ob.data.normalize, ob.data.energy = True, ob.data.energy * factor
    np.testing.assert_allclose(unnormalized, combined(engine, scene), rtol=1e-5, atol=1e-5)
    assert unnormalized[..., :3].max() > 0.1
