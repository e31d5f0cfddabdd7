"""What Lixel renders otherwise than Cycles is named in the render's warnings, not silently changed
(``describe.unmodelled_objects_note``): a Shadow Catcher, which Cycles shows as the background with the shadows on
it (measured in 5.0.1, a plane under a cube and a sun, a sky of (0.2, 0.3, 0.4) x 2: the unshadowed catcher 0.40 /
0.60 / 0.80 as the sky, transparent with Film Transparent; Lixel lit it as any surface, 0.83 / 0.99 / 1.15), and
hair curves, which Cycles renders as strands that cast shadows and Lixel does not draw. Before, neither was said."""
import bpy
import pytest

from test_render_engine import _render, add, build, scene  # noqa: F401


def _note(got) -> list:
    return [w for w in got["warnings"] if "Lixel does not draw" in w or "Shadow Catcher" in w]


def test_a_shadow_catcher_is_named(engine, scene):
    build(scene)
    assert not _note(_render(engine, scene))
    scene.objects["Ground"].is_shadow_catcher = True
    assert _note(_render(engine, scene)) == [
        "Lixel: object 'Ground' is a Shadow Catcher (Object properties > Visibility > Mask), which Lixel renders as an "
        "ordinary surface, not as the background with the shadows on it; switch it off, or render with Cycles for "
        "the catcher"]


@pytest.mark.parametrize("count", [1, 3])
def test_hair_curves_are_named_with_how_many_more(engine, scene, count):
    build(scene)
    made = []
    for i in range(count):
        curves = bpy.data.hair_curves.new(f"lixel_test hair {i}")
        curves.add_curves([3, 3])
        made.append(curves)
        add(scene, f"Hair {i}", curves)
    try:
        got = _note(_render(engine, scene))
    finally:
        for ob in [scene.objects[f"Hair {i}"] for i in range(count)]:
            bpy.data.objects.remove(ob)
        for curves in made:
            bpy.data.hair_curves.remove(curves)
    more = f" (and {count - 1} more such object(s))" if count > 1 else ""
    assert got == [f"Lixel: object 'Hair 0' is hair curves, which Lixel does not draw: it casts no shadow and is not "
                   f"seen (Lixel draws meshes, curves, surfaces, metaballs and text); convert it to a mesh (Object > "
                   f"Convert > Mesh) for its shadow{more}"]


def test_empty_hair_is_not_named(engine, scene):
    """A hair object with no curves (nothing Cycles would draw) says nothing."""
    build(scene)
    curves = bpy.data.hair_curves.new("lixel_test hair")
    ob = add(scene, "Hair", curves)
    try:
        assert not _note(_render(engine, scene))
    finally:
        bpy.data.objects.remove(ob)
        bpy.data.hair_curves.remove(curves)
