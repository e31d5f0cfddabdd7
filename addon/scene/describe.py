"""bpy -> the warp core's plain inputs: :class:`View`, :class:`Light`, :class:`SceneBounds`.

Everything returned is float64 numpy data that stays valid after the depsgraph
changes. Errors are :class:`WarpError` whose message names the object and says
what to do, fit for ``RenderEngine.report`` or an operator's ``self.report``.
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from ..warp.types import Light, SceneBounds, View, WarpError
from .instances import InstanceSet, walk_instances  # noqa: F401 (re-exported)

MAX_RESOLUTION = 16384
"""Largest render side Lixel accepts (the GPU's maximum texture size)."""

LIGHT_TYPES = ("SUN", "POINT", "SPOT", "AREA")
"""Blender light types Lixel shadows (AREA is approximated, see describe_light)."""

AREA_MAX_CONE = math.radians(179.0)


def _matrix(m) -> np.ndarray:
    return np.array(m, dtype=np.float64).reshape(4, 4)


def _evaluated(obj, depsgraph):
    if depsgraph is None:
        return obj
    try:
        return obj.evaluated_get(depsgraph)
    except (ReferenceError, RuntimeError):
        return obj


def render_resolution(scene) -> tuple[int, int]:
    """The output size in pixels, with the resolution percentage applied
    (Blender's own rounding: ``resolution * percentage // 100``)."""
    r = scene.render
    w = int(r.resolution_x) * int(r.resolution_percentage) // 100
    h = int(r.resolution_y) * int(r.resolution_percentage) // 100
    if w < 1 or h < 1:
        raise WarpError(f"Scene '{scene.name}' renders at {w}x{h} pixels: raise the resolution or its percentage "
                        f"(Output properties > Format)")
    if w > MAX_RESOLUTION or h > MAX_RESOLUTION:
        raise WarpError(f"Scene '{scene.name}' renders at {w}x{h} pixels, more than Lixel's limit of "
                        f"{MAX_RESOLUTION} per side: lower the resolution or its percentage (Output properties > Format)")
    return w, h


def describe_view(camera_obj, depsgraph, scene) -> View:
    """The camera as a :class:`View`.

    The projection is Blender's own ``Object.calc_matrix_camera`` at the render
    size and pixel aspect, so sensor fit, lens shift and orthographic scale are
    exactly what Blender renders (OpenGL-style: near -> z_ndc -1).
    ``camera_to_world`` is the evaluated ``matrix_world`` (constraints, drivers,
    animation applied).
    """
    if camera_obj is None:
        raise WarpError(f"Scene '{scene.name}' has no camera: add a camera and make it active (Scene properties > Camera)")
    if camera_obj.type != "CAMERA":
        raise WarpError(f"Object '{camera_obj.name}' is a {camera_obj.type.lower()}, not a camera: "
                        f"choose a camera object as the scene camera (Scene properties > Camera)")
    cam = camera_obj.data
    if cam.type == "PANO":
        raise WarpError(f"Camera '{camera_obj.name}' is panoramic: Lixel renders perspective and orthographic "
                        f"cameras; change its type (Camera properties > Lens > Type)")
    w, h = render_resolution(scene)
    r = scene.render
    ob_eval = _evaluated(camera_obj, depsgraph)
    projection = _matrix(ob_eval.calc_matrix_camera(depsgraph, x=w, y=h,
                                                    scale_x=float(r.pixel_aspect_x), scale_y=float(r.pixel_aspect_y)))
    near, far = float(cam.clip_start), float(cam.clip_end)
    if not (0 < near < far):
        raise WarpError(f"Camera '{camera_obj.name}' clips at start {near:g} and end {far:g}: the clip start must be "
                        f"positive and less than the clip end (Camera properties > Lens > Clip)")
    return View(
        camera_to_world=_matrix(ob_eval.matrix_world),
        projection=projection,
        near=near,
        far=far,
        resolution=(w, h),
        orthographic=cam.type == "ORTHO",
    )


def describe_light(light_obj, depsgraph=None) -> Light:
    """A Blender light object as a :class:`Light`, with its colour and energy.

    * SUN: ``direction`` = the object's world -Z.
    * POINT: ``position`` = the object's world location.
    * SPOT: position, direction (-Z) and ``spot_angle`` = ``spot_size`` (the
      full cone angle).
    * AREA: modelled as a SPOT at the light's centre facing its -Z with cone
      angle ``min(spread, 179°)``: hard shadows cast from the centre of the
      emitter (the soft penumbra of a finite emitter is not modelled). An area
      light's spread defaults to 180°, which no perspective map can cover, hence
      the 179° cap.

    Any other object raises :class:`WarpError` naming it.
    """
    if light_obj is None:
        raise WarpError("No light given: add a Sun, Point, Spot or Area light")
    if light_obj.type != "LIGHT":
        raise WarpError(f"Object '{light_obj.name}' is a {light_obj.type.lower()}, not a light: "
                        f"choose a Sun, Point, Spot or Area light as the Lixel light")
    data = light_obj.data
    kind = data.type
    if kind not in LIGHT_TYPES:
        raise WarpError(f"Light '{light_obj.name}' is of type {kind}, which Lixel cannot shadow: "
                        f"change it to Sun, Point, Spot or Area (Light properties)")
    m = _matrix(_evaluated(light_obj, depsgraph).matrix_world)
    position = m[:3, 3].copy()
    minus_z = -m[:3, 2]
    if not np.all(np.isfinite(m)) or np.linalg.norm(minus_z) < 1e-12:
        raise WarpError(f"Light '{light_obj.name}' has a degenerate transform (zero scale?): reset its rotation and scale")
    color = tuple(float(c) for c in data.color)
    energy = float(data.energy)
    name = light_obj.name
    if kind == "SUN":
        return Light("SUN", direction=minus_z, color=color, energy=energy, name=name)
    if kind == "POINT":
        return Light("POINT", position=position, color=color, energy=energy, name=name)
    if kind == "SPOT":
        return Light("SPOT", position=position, direction=minus_z, spot_angle=float(data.spot_size),
                     color=color, energy=energy, name=name)
    spread = float(getattr(data, "spread", math.pi))
    angle = min(spread, AREA_MAX_CONE)
    if angle <= 0:
        raise WarpError(f"Area light '{name}' has a spread of 0°: widen its spread (Light properties > Beam shape)")
    return Light("SPOT", position=position, direction=minus_z, spot_angle=angle, color=color, energy=energy, name=name)


def describe_bounds(depsgraph, instances: Optional[InstanceSet] = None) -> SceneBounds:
    """World AABBs of the evaluated scene's drawable instances.

    Casters are the instances whose object casts shadows (``visible_shadow``),
    receivers those the camera sees (``visible_camera``). Geometry-nodes, particle and collection
    instances are included (``depsgraph.object_instances``) with their own
    matrices. Pass the ``instances`` of an earlier :func:`walk_instances` to
    avoid walking the depsgraph again.
    """
    inst = walk_instances(depsgraph) if instances is None else instances
    boxes = inst.world_boxes()
    return SceneBounds(boxes[inst.casts], boxes[inst.receives])


def _scene_lights(scene, depsgraph) -> list:
    """Original light objects visible to this depsgraph (render or viewport), by name."""
    if depsgraph is not None:
        lights = [ob.original for ob in depsgraph.objects if ob.type == "LIGHT"]
    else:
        lights = [ob for ob in scene.objects if ob.type == "LIGHT" and not ob.hide_render]
    return sorted(lights, key=lambda o: o.name)


def _lixel_light_property(scene):
    props = getattr(scene, "lixel", None)
    if props is None:
        return None
    value = getattr(props, "light", None)
    if isinstance(value, str):
        import bpy
        return bpy.data.objects.get(value) if value else None
    return value


def pick_light(scene, depsgraph=None, active=None):
    """The light Lixel shadows: the scene's Lixel light (``scene.lixel.light``)
    if set, else the active object if it is a light, else the first sun, else
    the first light of a supported type (lights by name, for determinism)."""
    chosen = _lixel_light_property(scene)
    if chosen is not None:
        return chosen
    if active is not None and active.type == "LIGHT" and active.name in scene.objects:
        return active
    lights = _scene_lights(scene, depsgraph)
    for ob in lights:
        if ob.data.type == "SUN":
            return ob
    for ob in lights:
        if ob.data.type in LIGHT_TYPES:
            return ob
    if lights:
        kinds = ", ".join(sorted({o.data.type for o in lights}))
        raise WarpError(f"Scene '{scene.name}' has no light Lixel can shadow (found {kinds}): "
                        f"add a Sun, Point, Spot or Area light")
    raise WarpError(f"Scene '{scene.name}' has no light: add a Sun, Point, Spot or Area light (Add > Light)")


def evaluated_depsgraph(scene, view_layer=None):
    """The evaluated depsgraph of any scene (not only the window's): the view
    layer's own, created through a context override when it does not exist yet
    (a scene never shown has none)."""
    import bpy
    view_layer = view_layer or scene.view_layers[0]
    if bpy.context.scene == scene and bpy.context.view_layer == view_layer:
        return bpy.context.evaluated_depsgraph_get()
    dg = view_layer.depsgraph
    if dg is None:
        with bpy.context.temp_override(scene=scene, view_layer=view_layer):
            return bpy.context.evaluated_depsgraph_get()
    dg.update()
    return dg


def _resolve(obj_or_name):
    if isinstance(obj_or_name, str):
        import bpy
        ob = bpy.data.objects.get(obj_or_name)
        if ob is None:
            raise WarpError(f"There is no object named '{obj_or_name}'")
        return ob
    return obj_or_name


def describe_scene(context_or_scene, depsgraph=None, camera=None, light=None,
                   instances: Optional[InstanceSet] = None) -> tuple[View, Light, SceneBounds]:
    """(View, Light, SceneBounds) of a scene, ready for ``warp.compute``.

    ``context_or_scene``: a ``bpy.types.Context`` (its scene, evaluated
    depsgraph and active object are used) or a ``bpy.types.Scene``.
    ``depsgraph``: the evaluated depsgraph (a render engine passes its own);
    for a bare scene it defaults to the view layer's depsgraph, evaluated.
    ``camera``/``light``: objects (or names) overriding the scene camera and
    :func:`pick_light`'s choice.
    """
    import bpy

    if isinstance(context_or_scene, bpy.types.Context):
        ctx = context_or_scene
        scene = ctx.scene
        if depsgraph is None:
            depsgraph = ctx.evaluated_depsgraph_get()
        view_layer = ctx.view_layer
    else:
        scene = context_or_scene
        view_layer = depsgraph.view_layer if depsgraph is not None else scene.view_layers[0]
        if depsgraph is None:
            depsgraph = evaluated_depsgraph(scene, view_layer)
    active = view_layer.objects.active if view_layer is not None else None

    cam = _resolve(camera) if camera is not None else scene.camera
    view = describe_view(cam, depsgraph, scene)
    light_obj = _resolve(light) if light is not None else pick_light(scene, depsgraph, active)
    lit = describe_light(light_obj, depsgraph)
    bounds = describe_bounds(depsgraph, instances)
    if len(bounds.receivers) == 0:
        raise WarpError(f"Scene '{scene.name}' has no visible mesh, curve or text objects: "
                        f"add geometry to cast and receive shadows")
    return view, lit, bounds
