"""A light's Exposure, Temperature and Normalize (Blender 5.0's Light properties) light the frame as in Cycles:
Cycles scales the strength by 2^Exposure (measured in 5.0.1: a sun of Strength 3 at Exposure 1 renders as one of
Strength 6), multiplies the colour by the Temperature's blackbody (``Light.temperature_color``; 3000 K on a
(0.5, 1, 1) colour rendered (0.58, 0.56, 0.18) where (1, 1, 1) rendered (1.17, 0.57, 0.18)), and with Normalize off
multiplies the strength by the emitter's area (``describe.unnormalized_area``, measured). Lixel read the strength
and the colour alone: a frame half as bright, white, or 1/4 pi as bright (a point light of Radius 0.5)."""
import math

import bpy
import numpy as np
import pytest

from test_render_engine import _render, build, scene  # noqa: F401


def combined(engine, scene) -> np.ndarray:  # noqa: F811
    """F12's combined image, copied (the next render reuses its buffer)."""
    return np.array(_render(engine, scene)["result"].combined, dtype=np.float32)

pytestmark = pytest.mark.skipif("exposure" not in bpy.types.Light.bl_rna.properties,
                                reason="Blender 4.2 has no light Exposure nor Temperature")


def test_exposure_scales_the_strength_as_in_cycles(engine, scene):  # noqa: F811
    build(scene)
    sun = scene.objects["Sun"].data
    sun.energy = 2.0
    plain = combined(engine, scene)
    sun.exposure = 1.0
    exposed = combined(engine, scene)
    sun.energy, sun.exposure = 4.0, 0.0
    doubled = combined(engine, scene)
    np.testing.assert_allclose(exposed, doubled, atol=1e-5)
    assert (exposed[..., :3] > plain[..., :3] + 0.05).mean() > 0.25


def test_temperature_colours_the_light_as_in_cycles(engine, scene):  # noqa: F811
    build(scene)
    sun = scene.objects["Sun"].data
    sun.color, sun.use_temperature, sun.temperature = (0.5, 1.0, 1.0), True, 3000.0
    warm = combined(engine, scene)
    blackbody = tuple(sun.temperature_color)
    assert blackbody[0] > 1.5 and blackbody[2] < 0.5
    sun.use_temperature, sun.color = False, [c * t for c, t in zip((0.5, 1.0, 1.0), blackbody)]
    np.testing.assert_allclose(warm, combined(engine, scene), atol=1e-5)
    sun.color = (0.5, 1.0, 1.0)
    white = combined(engine, scene)
    assert (np.abs(warm[..., :3] - white[..., :3]) > 0.05).mean() > 0.25


EMITTERS = [("SUN", dict(angle=math.radians(10)), math.pi * math.sin(math.radians(5)) ** 2),
            ("POINT", dict(shadow_soft_size=0.5), math.pi),
            ("AREA", dict(shape="ELLIPSE", size=2.0, size_y=1.0), math.pi / 2)]
"""(type, its size, the area Cycles 5.0.1 multiplied the strength by with Normalize off, measured)."""


@pytest.mark.parametrize("kind, shape, area", EMITTERS)
def test_normalize_off_scales_the_strength_by_the_emitter_area(engine, scene, kind, shape, area):  # noqa: F811
    build(scene)
    scene.objects["Sun"].location = (1.0, -2.0, 5.0)
    light = scene.objects["Sun"].data
    light.type = kind
    light = scene.objects["Sun"].data
    for name, value in shape.items():
        setattr(light, name, value)
    light.energy = 3.0 if kind == "SUN" else 300.0
    normalized = combined(engine, scene)
    light.normalize = False
    unnormalized = combined(engine, scene)
    light.normalize, light.energy = True, light.energy * area
    np.testing.assert_allclose(unnormalized, combined(engine, scene), rtol=1e-5, atol=1e-5)
    assert not np.allclose(unnormalized, normalized, atol=0.05)
