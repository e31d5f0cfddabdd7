"""Lixel renders one light; the others of the frame are named in the render's warnings, not silently dropped
(``describe.other_lights_note``). Before, a 5000 W point light beside the sun changed no pixel of the render (Cycles
and EEVEE light with both) and nothing was said."""
import bpy

from test_render_engine import _render, add, build, scene  # noqa: F401


def _point(scene, name, energy=5000.0):
    light = add(scene, name, bpy.data.lights.new(name, "POINT"))
    light.data.energy, light.location = energy, (0.0, 0.0, 5.0)
    return light


def _notes(got) -> list:
    return [w for w in got["warnings"] if "more lights than" in w]


def test_a_second_light_is_named(engine, scene):
    build(scene)
    assert not _notes(_render(engine, scene))
    _point(scene, "Point")
    assert _notes(_render(engine, scene)) == [
        "Lixel: Scene 'lixel_test' has more lights than the one Lixel renders ('Sun'): light 'Point' lights nothing "
        "here, as if off; choose the light Lixel renders in the Lixel panel > Light, or render with Cycles or EEVEE "
        "for them all"]


def test_several_are_counted_and_lights_that_light_nothing_anyway_are_not(engine, scene):
    """A strength 0 light, one with Diffuse off and one hidden from renders light nothing in Cycles either."""
    build(scene)
    _point(scene, "Dark", 0.0)
    _point(scene, "No diffuse").visible_diffuse = False
    _point(scene, "Hidden").hide_render = True
    assert not _notes(_render(engine, scene))
    _point(scene, "A")
    _point(scene, "B")
    assert _notes(_render(engine, scene))[0].startswith(
        "Lixel: Scene 'lixel_test' has more lights than the one Lixel renders ('Sun'): lights 'A' and 1 more light "
        "nothing here")
