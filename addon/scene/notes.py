"""The scene's notes: what a frame renders otherwise than Cycles would, each naming the object and what to do.

One list, gathered here, for both places that say it: the render engine's warnings (F12, ``render_depsgraph``,
each prefixed "Lixel: ") and the 3D view's sidebar (``addon.ui.live`` keeps them with the live state, computed
when the state is updated, never per redraw). The light's own notes (``describe.light_notes``) are the light's
and shown with it; errors that leave a frame without shadows are not notes.
"""
from __future__ import annotations

from typing import Optional

from ..warp.types import SceneBounds, View
from .describe import (depth_of_field_note, evaluated, lost_depth_note, motion_blur_note, other_lights_note,
                       unmodelled_objects_note)
from .linking import linking_note
from .materials import material_holdout_note
from .world import WorldLight, world_light


def scene_notes(scene, depsgraph, light_obj, camera, view: View, bounds: SceneBounds, instances,
                world: Optional[WorldLight] = None) -> list[str]:
    """The notes of ``scene`` (the original) as ``depsgraph`` evaluates it, rendered with ``light_obj`` (None: no
    light) from the ``camera`` object and its ``view``, over ``bounds`` and the ``instances`` the geometry cache
    read: a camera whose far surfaces lose their depth, Motion Blur or Depth of Field asked for, a world that is not
    one colour (``world``: its :func:`world_light`, default that of the evaluated scene's world), a surface held
    out in part, objects Lixel does not model (a Shadow Catcher, hair curves, a point cloud, a volume), lights
    besides the one Lixel renders, and Light/Shadow Linking Lixel cannot follow. In that order; none: []."""
    world = world if world is not None else world_light(depsgraph.scene_eval.world)
    notes = (lost_depth_note(view, bounds, getattr(camera, "name", ""), scene), motion_blur_note(scene),
             depth_of_field_note(evaluated(camera, depsgraph) if camera is not None else None), world.note,
             material_holdout_note(depsgraph), unmodelled_objects_note(depsgraph),
             other_lights_note(light_obj, depsgraph, scene.name), linking_note(light_obj, instances))
    return [note for note in notes if note]
