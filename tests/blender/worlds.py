"""Worlds for the tests, lit as Cycles lights them in both Blender versions (addon/scene/world.py)."""
import bpy


def background(world):
    """The world's Background node, its nodes switched on first in 4.2 (5.0's worlds always have them)."""
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    return next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")


def sky_world(name: str, colour, strength: float = 1.0):
    """A new world whose Background node is ``colour`` at ``strength``: a sky of ``colour`` x ``strength`` in
    Cycles (and Lixel), 4.2 and 5.0 alike, where ``world.color`` is a new 5.0 world's viewport colour only."""
    world = bpy.data.worlds.new(name)
    node = background(world)
    node.inputs["Color"].default_value = (*colour, 1.0)
    node.inputs["Strength"].default_value = strength
    return world
