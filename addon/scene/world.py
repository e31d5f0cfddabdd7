"""The world's light as Cycles renders it: one constant colour, Lixel's ambient light and background.

Cycles lights and shows a world by its node tree where the world has one, and by ``world.color`` only where it has
none. Measured (a white diffuse plane lit by the world alone, 32x32, 16 samples, CPU; the plane and the background
both read the values below, in 5.0.1 and in 4.2.23 alike):

* a new world in 5.0 has nodes (``use_nodes`` is deprecated there, always on: setting it off changes nothing), its
  Background node at 0.05 grey, strength 1: ``world.color = (0.2, 0.3, 0.4)`` renders 0.05. In 4.2 a new world has
  no nodes and renders ``world.color``; switching its nodes on makes a Background of ``world.color`` at strength 1.
* Background (0.2, 0.3, 0.4) at strength 0.5 / 2: (0.1, 0.15, 0.2) / (0.4, 0.6, 0.8); an RGB node (0.5, 0.25, 0.1)
  into its Color and a Value node 1.5 into its Strength: (0.75, 0.375, 0.15); an Emission (0.2, 0.3, 0.4) at
  strength 2 into the World Output: (0.4, 0.6, 0.8); a Mix Shader at factor 0.25 of a red and a blue Background:
  (0.75, 0, 0.25); an output with nothing linked, or no world: black.
* two World Outputs: one of target Cycles wins over an active one of target EEVEE; of two of target All, the
  active one (``ShaderNodeTree.get_output_node('CYCLES')`` picks as Cycles does).
* a Sky Texture into the Background: the plane 12.1 / 10.5 / 9.2 (the sun), the sky behind it 0.01-0.04; an
  Environment Texture without an image: magenta (1, 0, 1). Not a constant: Lixel says so (:func:`world_light`).
* Film Transparent: the plane still lit by the world, the background alpha 0 (the engine's ``transparent``).
* World properties > Ray Visibility (``world.cycles_visibility``), a Background (0.2, 0.3, 0.4) x 2, with and
  without a sun of 2: Camera off, the sky behind the plane black (0, 0, 0), alpha 1, the plane lit as before (0.32 /
  0.48 / 0.64 by the world alone); Diffuse off, the sky as before (0.4 / 0.6 / 0.8) and the plane lit by the sun
  alone (0.51 grey; black without the sun). Lixel's surfaces are all diffuse: :func:`world_shading`.
"""
from __future__ import annotations

from typing import NamedTuple, Optional

import bpy

BLACK = (0.0, 0.0, 0.0)


class WorldLight(NamedTuple):
    """``colour``: the linear RGB radiance of the world in every direction, as Lixel lights and shows it;
    ``note``: a warning where that is not the world Cycles renders (None where it is)."""
    colour: tuple
    note: Optional[str]


class WorldShading(NamedTuple):
    """What the world gives the shading pass: ``ambient`` lights every (diffuse) surface, ``background`` is seen
    where no surface is; linear RGB each."""
    ambient: tuple
    background: tuple


def world_shading(world, light: Optional[WorldLight] = None, view_layer=None) -> WorldShading:
    """``light`` (default :func:`world_light` of ``world``) as the world's Ray Visibility lets Cycles see it (see the
    module's measurements): black behind the scene where Camera is off, no light on surfaces where Diffuse is off
    (Lixel's surfaces are all diffuse; Glossy, Transmission and Volume Scatter light none of them). A ``view_layer``
    with View Layer properties > Filter > Environment off has no world at all (Cycles, measured in 4.2.23 and 5.0.1:
    the plane and the sky both black)."""
    if view_layer is not None and not getattr(view_layer, "use_sky", True):
        return WorldShading(BLACK, BLACK)
    colour = (light or world_light(world)).colour
    rays = getattr(world, "cycles_visibility", None)
    return WorldShading(colour if rays is None or rays.diffuse else BLACK,
                        colour if rays is None or rays.camera else BLACK)


class _NotConstant(Exception):
    """A node whose output Lixel cannot evaluate to one constant; its message names the node."""


def _linked_from(socket):
    """The output socket feeding ``socket`` (through reroutes), or None where nothing (or a muted link) feeds it."""
    while True:
        links = [ln for ln in socket.links if ln.is_valid and not getattr(ln, "is_muted", False)]
        if not links:
            return None
        out = links[0].from_socket
        if out.node.type != "REROUTE":
            return out
        socket = out.node.inputs[0]


def _value(socket) -> tuple:
    """A colour or float input as RGB: its own value, or a linked RGB or Value node's (a Value into a colour is
    grey; an RGB into a float is Blender's luminance conversion, which Lixel does not model: not a constant here)."""
    out = _linked_from(socket)
    if out is None:
        value = socket.default_value
    elif (out.node.type == "VALUE" or (out.node.type == "RGB" and socket.type == "RGBA")) and not out.node.mute:
        value = out.default_value
    else:
        raise _NotConstant(out.node)
    if isinstance(value, float):
        return (value, value, value)
    return tuple(float(c) for c in value[:3])


def _shader(socket) -> tuple:
    """The constant RGB radiance a shader input emits, or :class:`_NotConstant` naming the node that is not one."""
    out = _linked_from(socket)
    if out is None:
        return BLACK
    node = out.node
    if node.mute:
        raise _NotConstant(node)
    if node.type in ("BACKGROUND", "EMISSION"):
        colour, strength = _value(node.inputs["Color"]), _value(node.inputs["Strength"])[0]
        return tuple(c * strength for c in colour)
    if node.type == "ADD_SHADER":
        a, b = _shader(node.inputs[0]), _shader(node.inputs[1])
        return tuple(x + y for x, y in zip(a, b))
    if node.type == "MIX_SHADER":
        fac = min(max(_value(node.inputs[0])[0], 0.0), 1.0)
        a, b = _shader(node.inputs[1]), _shader(node.inputs[2])
        return tuple((1.0 - fac) * x + fac * y for x, y in zip(a, b))
    raise _NotConstant(node)


def world_light(world) -> WorldLight:
    """The world's light as Cycles renders it, one constant (see the module's measurements): black for no world;
    ``world.color`` for a world without nodes (4.2's new worlds); else what its active Cycles output is fed, where
    that is a constant: Background and Emission nodes (colour x strength, either from the node or from a linked RGB
    or Value node), Mix and Add Shaders of those. Anything else (a sky or image texture, a Light Path trick, a node
    group) is not one colour: Lixel then lights with the world's viewport colour (``world.color``, World properties
    > Viewport Display), which the user can set to the sky's mean light, and the note names the world and the node."""
    if world is None:
        return WorldLight(BLACK, None)
    viewport = tuple(float(c) for c in world.color)
    # 5.0 deprecates use_nodes (always on; reading it warns); 4.2 renders world.color while it is off.
    tree = world.node_tree if bpy.app.version >= (5, 0, 0) or world.use_nodes else None
    if tree is None:
        return WorldLight(viewport, None)
    output = tree.get_output_node("CYCLES")
    if output is None:
        return WorldLight(BLACK, None)
    try:
        return WorldLight(_shader(output.inputs["Surface"]), None)
    except _NotConstant as exc:
        node = exc.args[0]
        what = f"{node.bl_label} node '{node.name}'" + (" (muted)" if node.mute else "")
        return WorldLight(viewport, (
            f"World '{world.name}' lights with its {what}, not one colour: Lixel lights every surface with its "
            f"viewport colour ({', '.join(f'{c:.3g}' for c in viewport)}) instead; set World properties > Viewport "
            f"Display > Color to the sky's mean light, or render with Cycles for the sky itself"))
