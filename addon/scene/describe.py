"""bpy -> the warp core's plain inputs: :class:`View`, :class:`Light`, :class:`SceneBounds`.

Everything returned is float64 numpy data that stays valid after the depsgraph
changes. Errors are :class:`WarpError` whose message names the object and says
what to do, fit for ``RenderEngine.report`` or an operator's ``self.report``.
"""
from __future__ import annotations

import math
import weakref
from typing import Optional

import numpy as np

from ..warp import MAX_COORDINATE, unresolved_frustum
from ..warp.geometry import frustum_matrix, ortho_matrix
from ..warp.methods import VISIBLE_RANGE_METHODS
from ..warp.polyhedron import box_corners
from ..warp.types import Light, SceneBounds, View, WarpError, clip_range_beyond_depth
from .instances import GEOMETRY_TYPES, InstanceSet, walk_instances  # noqa: F401 (re-exported)
from .units import length_text

MAX_RESOLUTION = 16384
"""Largest render side Lixel accepts (the GPU's maximum texture size)."""

DEPTH_STEP = 2.0 ** -23
"""The depth difference from the far plane below which a perspective camera's 32-bit float depth (z / w, computed
on the GPU) cannot tell a surface from the far plane, so it renders as background. Measured (5.0.1, the engine test's
ground and box seen from 9 m, clip end 10): at clip starts 1e-4, 1e-5, 3e-6 and 1e-6 the pixels lost are those beyond
n f / (n + DEPTH_STEP (f - n)) = 9.9, 8.9, 7.2 and 4.6 m (1 %, 6 %, 43 % and all of the ground seen)."""

LIGHT_TYPES = ("SUN", "POINT", "SPOT", "AREA")
"""Blender light types Lixel shadows (AREA is approximated, see describe_light)."""

MAX_CONE = math.radians(179.0)
"""The widest cone Lixel shadows with one perspective map: area lights' spread and 180° spots are narrowed to it."""


FLOAT32_MAX = float(np.finfo(np.float32).max)
"""Blender stores coordinates as float32 and clamps an infinity written to one
to this value, so a coordinate this large is an infinity that was clamped."""


def _finite(a: np.ndarray, axes) -> np.ndarray:
    """Per item: every value finite and below Blender's clamped infinity."""
    return (np.isfinite(a) & (np.abs(a) < FLOAT32_MAX)).all(axis=axes)


def _matrix(m) -> np.ndarray:
    return np.array(m, dtype=np.float64).reshape(4, 4)


def unscaled_camera_matrix(matrix, name: str) -> np.ndarray:
    """``matrix`` with each axis (column) normalised to unit length, as Blender's
    renderers take a camera (``normalize_m4`` of the object matrix in
    ``BKE_camera_multiview_model_matrix``): the object's scale is ignored, its
    translation and the directions of its axes are kept. A non-finite matrix, a
    zero-length axis (zero scale) or axes squeezed into a plane (a parent's
    non-uniform scale shearing it flat) raise WarpError naming the camera."""
    m = np.array(matrix, dtype=np.float64).reshape(4, 4)
    if not _finite(m, None):
        raise WarpError(f"Camera '{name}' has a non-finite transform (NaN or infinity in its location, rotation or "
                        f"scale, or a parent's): fix its transform (Object properties > Transform)")
    lengths = np.linalg.norm(m[:3, :3], axis=0)
    if not np.all(lengths > 0) or not np.all(np.isfinite(lengths)):
        axes = ", ".join(a for a, ok in zip("XYZ", lengths > 0) if not ok)
        raise WarpError(f"Camera '{name}' has zero scale on its {axes} {'axis' if len(axes) == 1 else 'axes'} (or a parent's), so it has no orientation: "
                        f"set its scale to 1 (Object properties > Transform > Scale); Blender ignores a camera's "
                        f"scale otherwise")
    m[:3, :3] /= lengths
    if abs(np.linalg.det(m[:3, :3])) < 1e-9:
        raise WarpError(f"Camera '{name}' is sheared flat (its axes are parallel, e.g. by a parent's non-uniform "
                        f"scale): clear its parent's scale or rotation (Object properties > Transform, Relations)")
    return m


def check_reach(what: str, position, scene) -> None:
    """WarpError naming ``what`` (a camera or a light) where ``position`` lies beyond :data:`MAX_COORDINATE`, in
    ``scene``'s units: the core's own check said "The camera's position reaches 2e+12 from the origin", naming no
    camera and in bare Blender units (2e10 m at a Unit Scale of 0.01)."""
    reach = float(np.abs(position).max())
    if reach > MAX_COORDINATE:
        raise WarpError(f"{what} is {length_text(reach, scene)} from the origin, beyond the "
                        f"{length_text(MAX_COORDINATE, scene)} Lixel can compute with: move it closer to the origin "
                        f"or scale the scene down")


def _a(noun: str) -> str:
    """``noun`` with its indefinite article ("an empty", "a mesh")."""
    return f"{'an' if noun[:1] in 'aeiou' else 'a'} {noun}"


def evaluated(obj, depsgraph):
    """``obj`` as ``depsgraph`` evaluates it (``obj`` itself without a depsgraph, or where it has no evaluated copy):
    its data (a light's strength and colour, a camera's clip range) with that depsgraph's frame's animation and
    drivers applied. An animation render's depsgraph leaves the original objects at the frame shown before it
    started, so values read from them are the same on every frame."""
    if depsgraph is None:
        return obj
    try:
        return obj.evaluated_get(depsgraph)
    except (ReferenceError, RuntimeError):
        return obj


def render_camera(scene, camera=None):
    """The camera Blender renders ``scene`` with: ``camera`` (a render's ``RenderEngine.camera_override``: the 3D
    view's Local Camera for F12 there, the timeline marker's camera in an animation) or ``scene.camera``, or with
    multi-view (Output > Stereoscopy > Multi-View) and one view, the scene's object named as that camera with the
    view's suffix in place of the longest view suffix ending its name, where there is one (Blender's
    ``camera_multiview_advanced``; measured in 4.2.23 and 5.0.1: "Cam_L" with only the right view renders "Cam_R").
    With several views the engine takes each view's camera from Blender (:func:`eye_view`)."""
    cam, r = camera or scene.camera, scene.render
    used = [v for v in r.views if v.use]
    if cam is None or not r.use_multiview or r.views_format != "MULTIVIEW" or len(used) != 1:
        return cam
    ends = [len(v.camera_suffix) for v in r.views if cam.name.endswith(v.camera_suffix)]
    if not ends:
        return cam
    return scene.objects.get(cam.name[:len(cam.name) - max(ends)] + used[0].camera_suffix, cam)


def render_views(scene) -> list[str]:
    """The views a render of ``scene`` makes (Output properties > Stereoscopy), as Blender's
    ``BKE_scene_multiview_is_render_view_active`` counts them: none without multi-view (one plain render), else
    each view switched on, of which Stereo 3D takes only "left" and "right"."""
    r = scene.render
    if not r.use_multiview:
        return []
    stereo = r.views_format == "STEREO_3D"
    return [v.name for v in r.views if v.use and (not stereo or v.name in ("left", "right"))]


def eye_view(view: View, camera_obj, model_matrix, shift_x: float, depsgraph=None) -> View:
    """``view`` (:func:`describe_view` of ``camera_obj``) seen from one view of a multi-view render: Blender's own
    matrix and horizontal lens shift for that view (``RenderEngine.camera_model_matrix`` and ``camera_shift_x``
    after ``active_view_set``: a stereo eye is moved by half the interocular distance, turned in with Toe-in, and
    shifted with Off-Axis convergence). The shift's change moves the projection's window as
    ``BKE_camera_params_compute_viewplane`` does: one unit of shift is the sensor-fit size, which the window's
    width 2 / P[0][0] holds sensor / lens times (perspective) or ortho_scale times (orthographic)."""
    cam = evaluated(camera_obj, depsgraph).data
    projection = view.projection.copy()
    if view.orthographic:
        projection[0, 3] -= (shift_x - cam.shift_x) * projection[0, 0] * cam.ortho_scale
    else:
        sensor = cam.sensor_height if cam.sensor_fit == "VERTICAL" else cam.sensor_width
        projection[0, 2] += (shift_x - cam.shift_x) * projection[0, 0] * sensor / cam.lens
    return View(unscaled_camera_matrix(model_matrix, camera_obj.name), projection, view.near, view.far,
                view.resolution, view.orthographic)


def lost_depth_note(view: View, bounds: SceneBounds, camera_name: str, scene=None) -> Optional[str]:
    """A warning when what the perspective ``view`` sees reaches beyond the distance where its depth can no longer be
    told from the far plane (:data:`DEPTH_STEP`), and that band is more than 1 % of its clip range: a clip start
    too small for its clip end (Blender's own engines lose it too), which renders those surfaces as background.
    Lengths in ``scene``'s units (:func:`length_text`)."""
    n, f = view.near, view.far
    lost = n * f / (n + DEPTH_STEP * (f - n))
    if view.orthographic or f - lost < 0.01 * (f - n) or len(bounds.receivers) == 0:
        return None
    farthest = float(view.eye_depth(box_corners(bounds.receivers[:, 0], bounds.receivers[:, 1])).max())
    if farthest <= lost:
        return None
    return (f"Camera '{camera_name}' clips from {length_text(n, scene)} to {length_text(f, scene)}: 32-bit depth "
            f"cannot tell its clip end from surfaces farther away than {length_text(lost, scene)}, so they render "
            f"as background; raise the clip start (Camera properties > Lens > Clip)")


def check_visible_range(view: View, settings, camera_name: str, scene) -> None:
    """WarpError when ``settings`` (LixelSettings) run a method of ``warp.methods.VISIBLE_RANGE_METHODS`` on a Custom
    Visible Range wholly outside the camera's clip range: it holds nothing the camera sees (LiSPSM and PSM computed as
    if it were not there, the cascade found no visible receiver). A range that overlaps the clip range is taken where it
    does (the methods clamp it); uniform and plane_optimal do not read it (the panel hides it for them)."""
    if settings.method not in VISIBLE_RANGE_METHODS or settings.warp.visible_depth_range is None:
        return
    near, far = settings.warp.visible_depth_range
    if not view.sees_depths(near, far):
        raise WarpError(f"Scene '{scene.name}' has a Visible Range from {length_text(near, scene)} to "
                        f"{length_text(far, scene)}, wholly outside the clip range of camera '{camera_name}' "
                        f"({length_text(view.near, scene)} to {length_text(view.far, scene)}), so it holds nothing "
                        f"the camera sees: set it within the clip range or turn Custom Visible Range off (Lixel "
                        f"panel > Method > Visible Range)")


def motion_blur_note(scene) -> Optional[str]:
    """A warning where ``scene`` asks for motion blur (Render properties > Motion Blur, set with Cycles or EEVEE,
    which blur what moves over the shutter around each frame): Lixel renders the frame's one instant."""
    if not scene.render.use_motion_blur:
        return None
    return (f"Scene '{scene.name}' has Motion Blur on: Lixel renders each frame at its one instant, unblurred (switch "
            f"Motion Blur off in Render properties with Cycles or EEVEE, or render there for blur)")


def depth_of_field_note(camera) -> Optional[str]:
    """A warning where ``camera`` (an object) has Depth of Field on (Camera properties > Depth of Field, which Cycles
    and EEVEE blur out of focus by its F-Stop): Lixel renders every distance in focus."""
    dof = getattr(getattr(camera, "data", None), "dof", None)
    if dof is None or not dof.use_dof:
        return None
    return (f"Camera '{camera.name}' has Depth of Field on: Lixel renders every distance in focus, unblurred (switch "
            f"it off in Camera properties > Depth of Field, or render with Cycles or EEVEE for the blur)")


UNDRAWN_TYPES = {"CURVES": "hair curves", "POINTCLOUD": "a point cloud", "VOLUME": "a volume"}
"""Object types Cycles renders (strands, points, a volume that shadows) and Lixel does not draw."""


def unmodelled_objects_note(depsgraph) -> Optional[str]:
    """A warning naming the first object of the frame Lixel renders otherwise than Cycles, and how many more there
    are: a Shadow Catcher (Object properties > Visibility > Mask; Cycles shows the background there with the shadows
    on it, measured in 5.0.1: the unshadowed catcher 0.40 / 0.60 / 0.80 under a sky of that colour, transparent with
    Film Transparent, where Lixel lit it as any surface, 0.83 / 0.99 / 1.15), or an object of a type Lixel does not
    draw (:data:`UNDRAWN_TYPES`: it casts no shadow and is not seen)."""
    found = []
    for ob in depsgraph.objects:
        if ob.type in UNDRAWN_TYPES:
            data = ob.data
            if len(getattr(data, "curves", getattr(data, "points", ()))) or (ob.type == "VOLUME" and len(data.grids)):
                found.append((ob.name, f"is {UNDRAWN_TYPES[ob.type]}, which Lixel does not draw: it casts no shadow "
                                       f"and is not seen (Lixel draws meshes, curves, surfaces, metaballs and text); "
                                       f"convert it to a mesh (Object > Convert > Mesh) for its shadow"))
        elif getattr(ob, "is_shadow_catcher", False) and ob.type in GEOMETRY_TYPES:
            found.append((ob.name, "is a Shadow Catcher (Object properties > Visibility > Mask), which Lixel renders as "
                                   "an ordinary surface, not as the background with the shadows on it; switch it off, "
                                   "or render with Cycles for the catcher"))
    if not found:
        return None
    more = f" (and {len(found) - 1} more such object(s))" if len(found) > 1 else ""
    return f"object '{found[0][0]}' {found[0][1]}{more}"


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
    exactly what Blender renders (OpenGL-style: near -> z_ndc -1); its depth rows
    are recomputed in float64 from the clip range (Blender returns float32, in
    which a wide clip range maps the far plane to infinity).
    ``camera_to_world`` is the evaluated ``matrix_world`` (constraints, drivers,
    animation applied) without its scale, which Blender's renderers ignore
    (:func:`unscaled_camera_matrix`). A degenerate camera (non-finite or zero-scale
    transform, a clip range beyond float precision) raises WarpError naming it. ``depsgraph`` None (a scene's
    ``view_layers[0].depsgraph`` where Blender never made one): the scene's own, evaluated
    (:func:`evaluated_depsgraph`); Blender's ``calc_matrix_camera`` crashed on None (segmentation fault).
    """
    if depsgraph is None:
        depsgraph = evaluated_depsgraph(scene)
    if camera_obj is None:
        raise WarpError(f"Scene '{scene.name}' has no camera: add a camera and make it active (Scene properties > Camera)")
    if camera_obj.type != "CAMERA":
        raise WarpError(f"Object '{camera_obj.name}' is {_a(camera_obj.type.lower())}, not a camera: "
                        f"choose a camera object as the scene camera (Scene properties > Camera)")
    ob_eval = evaluated(camera_obj, depsgraph)
    cam = ob_eval.data       # this frame's lens and clip range (an animation render's are not the original's)
    if cam.type == "PANO":
        raise WarpError(f"Camera '{camera_obj.name}' is panoramic: Lixel renders perspective and orthographic "
                        f"cameras; change its type (Camera properties > Lens > Type)")
    w, h = render_resolution(scene)
    r = scene.render
    near, far = float(cam.clip_start), float(cam.clip_end)
    if not (0 < near < far < math.inf):
        raise WarpError(f"Camera '{camera_obj.name}' clips at start {length_text(near, scene)} and end "
                        f"{length_text(far, scene)}: the clip start must be positive and less than the clip end "
                        f"(Camera properties > Lens > Clip)")
    if why := clip_range_beyond_depth(near, far, cam.type == "ORTHO", lambda v: length_text(v, scene)):  # ortho: any ratio
        raise WarpError(f"Camera '{camera_obj.name}' {why}: raise the clip start or lower the clip end "
                        f"(Camera properties > Lens > Clip)")
    camera_to_world = unscaled_camera_matrix(ob_eval.matrix_world, camera_obj.name)
    check_reach(f"Camera '{camera_obj.name}'", camera_to_world[:3, 3], scene)
    projection = _matrix(ob_eval.calc_matrix_camera(depsgraph, x=w, y=h,
                                                    scale_x=float(r.pixel_aspect_x), scale_y=float(r.pixel_aspect_y)))
    orthographic = cam.type == "ORTHO"
    projection[2:] = depth_rows(near, far, orthographic)
    if not np.all(np.isfinite(projection)) or projection[0, 0] == 0 or projection[1, 1] == 0:
        raise WarpError(f"Camera '{camera_obj.name}' has a degenerate lens (focal length, sensor or orthographic "
                        f"scale): fix it in Camera properties > Lens")
    view = View(camera_to_world=camera_to_world, projection=projection, near=near, far=far, resolution=(w, h),
                orthographic=orthographic)
    if why := unresolved_frustum(view, lambda v: length_text(v, scene)):     # (the core's words in bare units)
        raise WarpError(f"Camera '{camera_obj.name}': its view frustum {why}: widen its clip range (Camera "
                        f"properties > Lens > Clip) or move the scene closer to the origin")
    return view


def depth_rows(near: float, far: float, orthographic: bool) -> np.ndarray:
    """The z and w rows of Blender's camera projection (``perspective_m4`` /
    ``orthographic_m4``, OpenGL depth: near -> -1, far -> +1) in float64: the core's glOrtho / glFrustum rows."""
    return (ortho_matrix if orthographic else frustum_matrix)(-1.0, 1.0, -1.0, 1.0, near, far)[2:]


def area_light_area(data, matrix) -> float:
    """An area light's emitter area in square metres as Cycles lights with it: its square or rectangle (Size x Size Y)
    or disk or ellipse (pi/4 of that), stretched by the object's X and Y scale (``matrix``: its world matrix).
    Where it is 0 (a Size, Size Y or X/Y scale of 0), Cycles emits nothing from it, Normalize on or off (measured in
    4.2.23 and 5.0.1: a ground's mean 9.5e-9 against 0.081 at Size 0.5)."""
    x = float(data.size)
    y = x if data.shape in ("SQUARE", "DISK") else float(data.size_y)
    sx, sy = np.linalg.norm(np.asarray(matrix, dtype=float)[:3, :2], axis=0)
    return x * y * float(sx * sy) * (math.pi / 4.0 if data.shape in ("DISK", "ELLIPSE") else 1.0)


def unnormalized_area(data, matrix) -> float:
    """What Cycles multiplies a light's strength by where its Normalize is off (Blender 5.0; measured in 5.0.1
    against Normalize on, to 1e-6): the emitter's area. An area light's :func:`area_light_area`, a point or spot
    light's sphere 4 pi r^2 (r: its Radius; at Radius 0, 4), a sun's pi sin^2(angle / 2) (at Angle 0, 1)."""
    if data.type == "SUN":
        return math.pi * math.sin(float(data.angle) / 2.0) ** 2 if data.angle > 0 else 1.0
    if data.type in ("POINT", "SPOT"):
        return 4.0 * math.pi * float(data.shadow_soft_size) ** 2 if data.shadow_soft_size > 0 else 4.0
    return area_light_area(data, matrix)


def describe_light(light_obj, depsgraph=None, scene=None) -> Light:
    """A Blender light object as a :class:`Light`, with its colour and energy as Cycles takes them (Blender 5.0: the
    colour times the Temperature's blackbody where it is on, the strength times 2^Exposure, and times the emitter's
    area where Normalize is off: :func:`unnormalized_area`). An area light of no area emits nothing, as in Cycles.

    * SUN: ``direction`` = the object's world -Z.
    * POINT: ``position`` = the object's world location.
    * SPOT: position, direction (-Z) and ``spot_angle`` = ``spot_size`` (the
      full cone angle; Blender's 180° at most is narrowed to ``MAX_CONE``, 179°).
    * AREA: modelled as a SPOT at the light's centre facing its -Z with cone
      angle ``min(spread, 179°)``: hard shadows cast from the centre of the
      emitter (the soft penumbra of a finite emitter is not modelled). An area
      light's spread defaults to 180°, which no perspective map can cover, hence
      the 179° cap.

    A light that lights no surface (:func:`lights_surfaces`) has an energy of 0: its shadows show only in the
    Shadow pass. Any other object, a light beyond :data:`MAX_COORDINATE` (a sun has no position), or one whose
    strength or colour a script made NaN (F12 rendered black, without a word) raises :class:`WarpError` naming it
    (lengths in ``scene``'s units).
    """
    if light_obj is None:
        raise WarpError("No light given: add a Sun, Point, Spot or Area light")
    if light_obj.type != "LIGHT":
        raise WarpError(f"Object '{light_obj.name}' is {_a(light_obj.type.lower())}, not a light: "
                        f"choose a Sun, Point, Spot or Area light as the Lixel light")
    light_eval = evaluated(light_obj, depsgraph)
    data = light_eval.data    # this frame's strength, colour and cone
    kind = data.type
    if kind not in LIGHT_TYPES:
        raise WarpError(f"Light '{light_obj.name}' is of type {kind}, which Lixel cannot shadow: "
                        f"change it to Sun, Point, Spot or Area (Light properties)")
    m = _instance_matrix(light_obj, depsgraph)
    m = _matrix(light_eval.matrix_world) if m is None else m
    if not _finite(m, None):
        raise WarpError(f"Light '{light_obj.name}' has a non-finite transform (NaN or infinity in its location, "
                        f"rotation or scale, or a parent's): fix its transform (Object properties > Transform)")
    position = m[:3, 3].copy()
    if kind != "SUN":
        check_reach(f"Light '{light_obj.name}'", position, scene)
    minus_z = -m[:3, 2]
    z_length = float(np.linalg.norm(minus_z))
    if kind != "POINT" and not 0 < z_length < math.inf:
        raise WarpError(f"Light '{light_obj.name}' has zero scale on its Z axis (or a parent's), so it points "
                        f"nowhere: set its scale to 1 (Object properties > Transform > Scale)")
    minus_z = minus_z / z_length if z_length > 0 else minus_z
    color = tuple(float(c) for c in data.color)
    if getattr(data, "use_temperature", False):   # 5.0: Cycles multiplies the colour by the Temperature's blackbody
        color = tuple(c * float(t) for c, t in zip(color, data.temperature_color))
    # 5.0's Exposure scales the strength by 2^exposure in Cycles (measured: Strength 3 at Exposure 1 renders as 6)
    emits = lights_surfaces(light_eval) and (kind != "AREA" or area_light_area(data, m) > 0)
    energy = float(data.energy) * 2.0 ** float(getattr(data, "exposure", 0.0)) if emits else 0.0
    if not getattr(data, "normalize", True):
        energy *= unnormalized_area(data, m)
    name = light_obj.name
    if not all(math.isfinite(v) for v in (energy, *color)):     # Blender's fields let a script's NaN through
        raise WarpError(f"Light '{name}' has a strength or colour of NaN or infinity (set from a script?), which "
                        f"lit nothing and rendered black: give it a number (Light properties > Power/Strength, "
                        f"Color, Exposure)")
    if kind == "SUN":
        return Light("SUN", direction=minus_z, color=color, energy=energy, name=name)
    if kind == "POINT":
        return Light("POINT", position=position, color=color, energy=energy, name=name)
    if kind == "SPOT":  # Blender allows 180°, which no perspective map covers: 179°, as for an area light
        return Light("SPOT", position=position, direction=minus_z, spot_angle=min(float(data.spot_size), MAX_CONE),
                     color=color, energy=energy, name=name)
    spread = float(getattr(data, "spread", math.pi))
    angle = min(spread, MAX_CONE)
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
    check_finite_instances(inst, depsgraph.scene)
    return inst.bounds  # made once per instance set, with its culling index


def _first_bad(inst: InstanceSet, bad: np.ndarray) -> str:
    return inst.names[int(np.flatnonzero(bad)[0])]


_finite_sets: "weakref.WeakSet" = weakref.WeakSet()
"""Instance sets already found finite (a cache hands out the same set while the scene is unchanged)."""


def check_finite_instances(inst: InstanceSet, scene=None) -> None:
    """Refuse a scene with non-finite numbers in an object's transform or bounds,
    naming the first such object (a NaN would silently spread through B and the
    maps), or reaching beyond :data:`MAX_COORDINATE` (in ``scene``'s units). Each instance set is checked once."""
    if len(inst) == 0 or inst in _finite_sets:
        return
    bad = ~_finite(inst.matrices, (1, 2))
    if bad.any():
        raise WarpError(f"Object '{_first_bad(inst, bad)}' has a non-finite transform (NaN or infinity in its location, "
                        f"rotation or scale, or a parent's): fix its transform (Object properties > Transform)")
    bad = ~_finite(inst.local_boxes, (1, 2))
    if bad.any():
        raise WarpError(f"Object '{_first_bad(inst, bad)}' has vertices with non-finite coordinates (NaN or infinity): "
                        f"fix or delete them (Edit Mode; Mesh > Clean Up)")
    with np.errstate(over="ignore", invalid="ignore"):
        reach = np.abs(inst.world_boxes()).max(axis=(1, 2))
    bad = ~np.isfinite(reach)
    if bad.any():
        raise WarpError(f"Object '{_first_bad(inst, bad)}' reaches beyond the range of floating-point numbers: "
                        f"scale it down or move it closer to the origin")
    bad = (reach > MAX_COORDINATE) & (inst.casts | inst.receives)   # as the core would refuse "the scene's boxes"
    if bad.any():
        raise WarpError(f"Object '{_first_bad(inst, bad)}' reaches {length_text(reach[bad].max(), scene)} from the "
                        f"origin, beyond the {length_text(MAX_COORDINATE, scene)} Lixel can compute with: move it "
                        f"closer to the origin or scale it down")
    _finite_sets.add(inst)


_finite_meshes: "weakref.WeakValueDictionary" = weakref.WeakValueDictionary()
"""id -> mesh (``addon.scene.geometry.MeshData``) already found finite: each is checked once
(a new version of a mesh is a new object)."""


def check_finite_geometry(geometry) -> None:
    """Refuse triangles with NaN or infinite vertex coordinates, naming the object
    (Blender's bounding box may skip a NaN vertex, so the bounds alone do not
    show it). Each mesh version is checked once."""
    inst = geometry.instances
    for key, mesh in geometry.meshes.items():
        if _finite_meshes.get(id(mesh)) is mesh:
            continue
        if not _finite(mesh.positions, None):
            where = [i for i, k in enumerate(inst.keys) if k == key]
            name = inst.names[where[0]] if where else key[1]
            raise WarpError(f"Object '{name}' has vertices with non-finite coordinates (NaN or infinity): "
                            f"fix or delete them (Edit Mode; Mesh > Clean Up)")
        _finite_meshes[id(mesh)] = mesh


NO_FACES = "has no visible faces (no mesh, curve or text object with faces)"
"""What a scene lacks where nothing can receive a shadow: an object of only edges or points shades nothing."""


def lights_surfaces(light_obj) -> bool:
    """Whether ``light_obj`` lights Lixel's surfaces, which are all diffuse: its Ray Visibility > Diffuse (Object
    properties > Visibility) is on. With it off, Cycles and EEVEE light no diffuse surface with it (measured in 4.2.23
    and 5.0.1, a sun-lit ground and box: the picture's mean 0.58 -> 0.05 in Cycles, 0.55 -> 0.05 in EEVEE, the
    world's light alone). EEVEE also scales it by the light's Diffuse factor, which Cycles and Lixel ignore."""
    return bool(getattr(light_obj, "visible_diffuse", True))


def light_notes(light_obj, depsgraph=None) -> list[str]:
    """Warnings about a light Lixel renders but that may surprise: one that lights no surface
    (:func:`lights_surfaces`), no strength, or a negative one (which Cycles and Lixel subtract), an area light
    approximated by a spot, a spot scaled unevenly (Blender stretches its cone by the X and Y scale against the Z
    scale; Lixel's cone is round), as ``depsgraph`` evaluates it (:func:`evaluated`)."""
    notes = []
    light_obj = evaluated(light_obj, depsgraph) if light_obj is not None else None
    data = getattr(light_obj, "data", None)
    if data is None:
        return notes
    energy = float(getattr(data, "energy", 1.0))
    if not lights_surfaces(light_obj):
        notes.append(f"Light '{light_obj.name}' has Diffuse off in its Ray Visibility: as in Cycles and EEVEE it "
                     f"lights no surface, so its shadows show only in the Shadow pass (Object properties > "
                     f"Visibility > Ray Visibility)")
    elif energy == 0:
        notes.append(f"Light '{light_obj.name}' has a strength of 0: it lights nothing, so its shadows show "
                     f"only in the Shadow pass (Light properties > Power/Strength)")
    elif energy < 0:     # Cycles subtracts such a light (measured in 5.0.1: a sun of -1 darkens the world's 0.40 to 0.12)
        notes.append(f"Light '{light_obj.name}' has a negative strength ({energy:g}): it takes light away, as in "
                     f"Cycles, so its shadows are the brighter places (Light properties > Power/Strength)")
    if data.type == "AREA" and area_light_area(data, light_obj.matrix_world) <= 0:
        notes.append(f"Area light '{light_obj.name}' has no area (a Size, Size Y or X/Y scale of 0): as in Cycles it "
                     f"emits nothing, so its shadows show only in the Shadow pass; give it a size (Light properties > "
                     f"Size) and a scale (Object properties > Transform > Scale)")
    elif data.type == "AREA":
        notes.append(f"Area light '{light_obj.name}' is shadowed as a spot light at its centre (hard shadows, "
                     f"cone = its spread, at most 179°)")
    if data.type == "SPOT" and data.spot_size > MAX_CONE:
        notes.append(f"Spot light '{light_obj.name}' has a cone of {math.degrees(data.spot_size):.4g}°: Lixel lights "
                     f"and shadows its 179° (no perspective map covers 180°); the rim beyond is unlit")
    sx, sy, sz = np.linalg.norm(_matrix(light_obj.matrix_world)[:3, :3], axis=0)
    if data.type == "SPOT" and sz > 0 and not np.allclose((sx, sy), sz, rtol=1e-4, atol=0):
        notes.append(f"Spot light '{light_obj.name}' is scaled unevenly (X {sx / sz:.3g}, Y {sy / sz:.3g} times its "
                     f"Z): Blender stretches its cone into an ellipse, Lixel lights and shadows the round cone of its "
                     f"Spot Size; give it an even scale (Object properties > Transform > Scale)")
    return notes


def shadow_off(light_obj, depsgraph=None) -> Optional[str]:
    """Why ``light_obj`` casts no shadow where its Shadow is off (Light properties > Shadow: Cycles and EEVEE light
    with it, unshadowed), as ``depsgraph`` evaluates it (:func:`evaluated`); None where it casts them."""
    data = getattr(evaluated(light_obj, depsgraph), "data", None) if light_obj is not None else None
    if getattr(data, "use_shadow", True):
        return None
    return (f"light '{light_obj.name}' casts no shadows, as in Blender's engines: its Shadow is off (Light properties "
            f"> Shadow)")


def other_lights_note(light_obj, depsgraph, scene_name: str) -> Optional[str]:
    """A warning naming the lights of the frame besides ``light_obj`` that would light it in Cycles and EEVEE (shown
    in ``depsgraph``, a strength other than 0, Diffuse on): Lixel renders one light, so they light nothing here.
    (Before, a 5000 W point light beside the sun changed no pixel and nothing was said.)"""
    chosen = light_obj.original if light_obj is not None else None
    others = sorted({ob.name for ob in depsgraph.objects if ob.type == "LIGHT" and ob.original != chosen
                     and float(getattr(ob.data, "energy", 1.0)) != 0 and lights_surfaces(ob)})
    if not others or chosen is None:
        return None
    which = f"light '{others[0]}' lights" if len(others) == 1 else \
        f"lights '{others[0]}' and {len(others) - 1} more light"
    return (f"Scene '{scene_name}' has more lights than the one Lixel renders ('{chosen.name}'): {which} nothing "
            f"here, as if off; choose the light Lixel renders in the Lixel panel > Light, or render with Cycles or "
            f"EEVEE for them all")


def _scene_lights(scene, depsgraph) -> list:
    """Original light objects visible to this depsgraph (render or viewport), by name."""
    if depsgraph is not None:
        lights = [ob.original for ob in depsgraph.objects if ob.type == "LIGHT"]
    else:
        lights = [ob for ob in scene.objects if ob.type == "LIGHT" and not ob.hide_render]
    return sorted(lights, key=lambda o: o.name)


def _instanced_lights(depsgraph) -> list:
    """Original light objects the depsgraph shows only as instances: a collection instance (File > Link of a
    collection makes one: a linked lighting rig), by name."""
    found: list = []
    for inst in depsgraph.object_instances:
        if inst.is_instance and inst.object.type == "LIGHT" and inst.object.original not in found:
            found.append(inst.object.original)
    return sorted(found, key=lambda o: o.name)


def _instance_matrix(light_obj, depsgraph) -> Optional[np.ndarray]:
    """The world matrix of a light the scene holds only through instances (its first instance's, as Blender lights
    with each), or None for a light of the scene's own (its matrix_world)."""
    if depsgraph is None or depsgraph.scene.objects.get(light_obj.name) == light_obj:
        return None
    for inst in depsgraph.object_instances:
        if inst.is_instance and inst.object.original == light_obj:
            return _matrix(inst.matrix_world)
    return None


def _lixel_light_property(scene):
    props = getattr(scene, "lixel", None)
    if props is None:
        return None
    value = getattr(props, "light", None)
    if isinstance(value, str):
        import bpy
        return bpy.data.objects.get(value) if value else None
    return value


class NoLightError(WarpError):
    """The scene shows no light Lixel could shadow (none, or the Lixel light hidden): Blender's engines light such a
    frame by the world alone, and so does the LIXEL engine (``describe_scene(need_light=False)``)."""


def pick_light(scene, depsgraph=None, active=None, chosen=None):
    """The light Lixel shadows: ``chosen`` (a script's ``--light``) or the scene's Lixel light (``scene.lixel.light``)
    if set, else the active object if it is a light, else the first sun, else
    the first light of a supported type (lights by name, for determinism). Only
    a light the scene shows in ``depsgraph`` (render or viewport) counts: a Lixel
    light hidden there, or in another scene, lights nothing in Blender and is
    refused by name. Lights shown only as instances (a linked lighting rig) count when the scene's own lights
    do not answer. No light shown, or the Lixel light hidden: :class:`NoLightError`."""
    lights = _scene_lights(scene, depsgraph)
    chosen = chosen if chosen is not None else _lixel_light_property(scene)
    if depsgraph is not None and (chosen not in lights if chosen is not None else
                                  not any(ob.data.type in LIGHT_TYPES for ob in lights)):
        lights += _instanced_lights(depsgraph)      # walked only when the scene's own lights do not answer
    if chosen is not None:
        if chosen.type != "LIGHT":    # (a script sets the panel's Light past its poll)
            raise NoLightError(f"The Lixel light '{chosen.name}' is {_a(chosen.type.lower())}, not a light: choose a "
                               f"light (Lixel panel > Light)")
        if chosen not in lights:
            raise NoLightError(f"The Lixel light '{chosen.name}' is not among the lights scene '{scene.name}' shows "
                               f"(hidden, in an excluded collection or in another scene), so Blender lights nothing "
                               f"with it: show it, or choose another light (Lixel panel > Light; a script's --light)")
        return chosen
    if active is not None and active.type == "LIGHT" and active in lights:
        return active
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
    raise NoLightError(f"Scene '{scene.name}' has no light: add a Sun, Point, Spot or Area light (Add > Light)")


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
                   instances: Optional[InstanceSet] = None, need_receivers: bool = True, need_light: bool = True
                   ) -> tuple[View, Optional[Light], SceneBounds]:
    """(View, Light, SceneBounds) of a scene, ready for ``warp.compute``.

    ``context_or_scene``: a ``bpy.types.Context`` (its scene, evaluated
    depsgraph and active object are used) or a ``bpy.types.Scene``.
    ``depsgraph``: the evaluated depsgraph (a render engine passes its own);
    for a bare scene it defaults to the view layer's depsgraph, evaluated.
    ``camera``/``light``: objects (or names) overriding the scene camera and
    :func:`pick_light`'s choice. ``need_receivers``: a scene the camera can see nothing of (no visible faces: mesh, curve
    or text object) raises WarpError; False: its bounds have no receivers (a render shows the world background).
    ``need_light``: a scene that shows no light raises :class:`NoLightError`; False: the Light is None (a render
    shows the world's light alone).
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

    cam = _resolve(camera) if camera is not None else render_camera(scene)
    view = describe_view(cam, depsgraph, scene)
    try:
        light_obj = _resolve(light) if light is not None else pick_light(scene, depsgraph, active)
    except NoLightError:
        if need_light:
            raise
        light_obj = None
    lit = describe_light(light_obj, depsgraph, scene) if light_obj is not None else None
    bounds = describe_bounds(depsgraph, instances)
    if need_receivers and len(bounds.receivers) == 0:
        raise WarpError(f"Scene '{scene.name}' {NO_FACES}: add geometry to cast and receive shadows")
    return view, lit, bounds
