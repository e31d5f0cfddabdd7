"""What of a surface's material Lixel follows: a Holdout shader. Every other material is Lixel's one diffuse grey.

A material whose active Cycles output is fed a Holdout shader (Add > Shader > Holdout) makes Cycles render its
surface as an object held out renders (measured, 4.2.23 and 5.0.1, a cube before a box on a sun-lit ground, 64
samples: the cube a transparent hole, (0.01, 0.01, 0.01, 0.03) at its anti-aliased edges; every other pixel as with
Object > Visibility > Holdout on, mean difference 0.008, within the noise, its shadow kept, where hiding the cube
differs by 0.02, up to 0.68). Lixel holds such an object out (``instances.holdout_test``). Where only some of an
object's materials hold out, or a Holdout is mixed into a shader, Cycles holds out part of the surface (faces
with two such slots: mean alpha 0.48 over the cube), which Lixel does not model: :func:`material_holdout_note`
names the object and the material.
"""
from __future__ import annotations

from typing import Optional


def _surface_nodes(material) -> tuple:
    """(the node feeding the material's active Cycles output's Surface or None, every node upstream of it)."""
    import bpy

    from .world import _linked_from
    tree = None
    if material is not None and (bpy.app.version >= (5, 0, 0) or material.use_nodes):   # 5.0: always nodes
        tree = material.node_tree
    output = tree.get_output_node("CYCLES") if tree is not None else None
    first = _linked_from(output.inputs["Surface"]) if output is not None else None
    seen, todo = [], [first.node] if first is not None else []
    while todo:
        node = todo.pop()
        if node in seen:
            continue
        seen.append(node)
        todo += [out.node for out in (_linked_from(s) for s in node.inputs) if out is not None]
    return (first.node if first is not None else None), seen


def holds_out(material) -> Optional[bool]:
    """True where ``material``'s surface is a Holdout shader (not muted), False where no Holdout feeds it, None
    where one is mixed in (the surface partly held out)."""
    first, upstream = _surface_nodes(material)
    if first is not None and first.type == "HOLDOUT" and not first.mute:
        return True
    return None if any(n.type == "HOLDOUT" and not n.mute for n in upstream) else False


def any_holdout_material() -> bool:
    """Whether any material of the file has a Holdout node (only then is each object's looked at)."""
    import bpy
    return any(n.type == "HOLDOUT" for m in bpy.data.materials if m.node_tree is not None for n in m.node_tree.nodes)


def materials_of(ob, mesh=None) -> list:
    """The materials ``ob``'s surface renders with (``mesh``: a geometry-nodes mesh drawn for it instead)."""
    if mesh is not None:
        return list(mesh.materials)
    return [slot.material for slot in ob.material_slots]


def surface_held_out(ob, mesh=None) -> bool:
    """Whether every material of ``ob``'s surface (at least one) is a Holdout: Cycles holds the whole surface out."""
    materials = materials_of(ob, mesh)
    return bool(materials) and all(holds_out(m) is True for m in materials)


def material_holdout_note(depsgraph) -> Optional[str]:
    """A warning naming the first object whose surface holds out in part (see the module docstring), or None."""
    if not any_holdout_material():
        return None
    for ob in depsgraph.objects:
        if ob.type not in ("MESH", "CURVE", "SURFACE", "META", "FONT"):
            continue
        verdicts = [(m, holds_out(m)) for m in materials_of(ob)]
        if any(v is not False for _, v in verdicts) and not all(v is True for _, v in verdicts):
            partial = next(m for m, v in verdicts if v is not False)
            return (f"object '{ob.name}' holds out only part of its surface (material '{partial.name}' has a "
                    f"Holdout shader, its other materials or shaders do not): Lixel renders its whole surface as "
                    f"not held out; give all its material slots the Holdout, or use Object properties > Visibility "
                    f"> Holdout")
    return None
