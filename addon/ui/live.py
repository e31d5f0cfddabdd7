"""The live Lixel state of each scene: its inputs (view, light, bounds,
settings), B, the shadow setup, the overlay geometry and what each step cost.

:func:`update` recomputes only what changed: a moved camera re-describes the
view but reuses the scene bounds; B is rebuilt only when the view, light or
bounds differ from last time; the setup only when B or the settings differ;
the overlay geometry only when the setup did. The timings of the last update
are kept for the panel's readouts. Operators, the panel, the overlays, the
depsgraph handler and the background scripts all go through here.

While the view moves (``moving=True``: the depsgraph and frame-change handlers), a cascade whose split depths
would be searched (``adaptive_splits``: most of its cost) takes the PSSM λ splits instead (``cascade_adaptive``
off, everything else as the settings say; ``bench.live_drag``: 108-139 -> 49-83 ms a change of view) and is marked
``provisional``; :func:`refine_when_resting` arms one timer, re-armed by each change, that recomputes it with the
user's settings once the view has rested :data:`REST_S` (:func:`refine`), as Blender's viewport refines when the
view rests. Every other caller (operators, scripts, the engine's own path) gets the full result: an update that is
not ``moving`` recomputes a provisional setup even when nothing else changed.

The state is runtime only (never saved): it is dropped on file load. It is
keyed by the scene's ``session_uid`` (:func:`scene_key`), not its name: a rename
keeps it, a new scene that takes a deleted one's name starts without one.
"""
from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass, field
from typing import Optional

import bpy
import numpy as np

from ..cli.output import PLANE_OPTION, name_in_notes, name_receivers
from ..gpu.blas import one_blas_thread
from ..guard import guarded_callback, user_message
from ..scene.describe import (NO_FACES, check_finite_geometry, check_visible_range, describe_bounds, describe_light,
                              describe_view, evaluated_depsgraph, light_notes, pick_light, render_camera, shadow_off)
from ..scene.geometry import shared_cache
from ..scene.notes import scene_notes
from ..scene.owned import is_debug_object
from ..scene.units import length_text
from ..settings import LixelSettings
from ..warp import METHODS, compute, focused_body
from ..warp.methods.cascade import adaptive_splits
from ..warp.types import EmptyBodyError, WarpError
from .overlay_geometry import footprint_estimate, overlay_geometry

log = logging.getLogger(__name__)

INPUTS = ("view", "light", "bounds", "settings")
REST_S = 0.3
"""Seconds without a change of view (or light, bounds, settings) after which a provisional cascade is refined."""

NOTE_KINDS = ("λ guard",)
"""Entries of ``Diagnostics.fallbacks`` that are notes, not fallbacks: the method kept its own
construction and adjusted a parameter (the λ guard raising λ so the warp is no worse than the
uniform map, docs/papers.md "The λ guard")."""


def fallbacks_and_notes(diagnostics) -> tuple[list, list]:
    """The diagnostics' (what, reason) pairs split into what the method did
    instead of its own construction, and notes (:data:`NOTE_KINDS`)."""
    fallbacks, notes = [], []
    for what, why in diagnostics.fallbacks:
        (notes if what.split(": ")[-1] in NOTE_KINDS else fallbacks).append((what, why))
    return fallbacks, notes


def scene_geometry(depsgraph):
    """The evaluated scene's triangles without Lixel's debug objects, from the
    scene cache the render engine uses too (``addon.scene.geometry.shared_cache``).
    A mesh with a NaN or infinite vertex raises WarpError naming its object, as a
    render does: Blender 5.0's object bounds skip such a vertex, so only the
    triangles show it (each version of a mesh is checked once, when the cache reads it)."""
    geometry = shared_cache().update(depsgraph, exclude=is_debug_object)
    check_finite_geometry(geometry)
    return geometry


def scene_bounds(depsgraph) -> tuple:
    """(SceneBounds, InstanceSet) of the evaluated scene's geometry (:func:`scene_geometry`): the
    same objects, the bounds with their culling index, while the scene's instances are unchanged."""
    instances = scene_geometry(depsgraph).instances
    return describe_bounds(depsgraph, instances), instances


@dataclass
class LiveState:
    """One scene's last computation (everything plain data)."""

    scene_name: str
    view: object = None
    light: object = None
    light_name: str = ""
    light_notes: tuple = ()
    light_pointer: int = 0
    """The light object's ``as_pointer()`` (its Light/Shadow Linking, for the picture: ``renders.pip_textures``)."""
    bounds: object = None
    instances: object = None
    """The ``InstanceSet`` the bounds were made from (its Light/Shadow Linking readers, for the notes)."""
    notes: tuple = ()
    """The scene's notes (``addon.scene.notes.scene_notes``: the render's warnings, without "Lixel: "), gathered
    when :func:`update` is told of a change, never per redraw; () where none, or where describing failed."""
    settings: Optional[LixelSettings] = None
    method_used: str = ""
    body: object = None
    setup: object = None
    geometry: Optional[dict] = None
    footprint: Optional[dict] = None
    error: str = ""
    note: str = ""
    timings: dict = field(default_factory=dict)
    recomputed: tuple = ()
    generation: int = 0
    """Bumped whenever the setup or geometry changes (overlays rebuild GPU batches on change)."""
    camera_name: str = ""
    """The 3D view's Local Camera the state follows (:func:`follow`); "": the scene's camera (``render_camera``)."""
    provisional: bool = False
    """The setup is a moving view's: the cascade's λ splits stand in for its adaptive ones until :func:`refine`."""
    empty_body: str = ""
    """Why nothing the camera sees can be shadowed (the core's EmptyBodyError), where that is the ``error``: F12
    renders such a frame unshadowed, with a warning (``render_method.py`` does too)."""

    @property
    def ok(self) -> bool:
        return self.setup is not None and not self.error

    def total_ms(self) -> float:
        return float(sum(self.timings.values()))


_states: dict[int, LiveState] = {}


def scene_key(scene) -> int:
    """What identifies ``scene`` in this session: its ``session_uid`` (4.2 and 5.0),
    kept across renames and undo steps and never given to another scene; a file
    load makes new ones, and :func:`clear` drops the states then."""
    return scene.session_uid


def living_scene_keys() -> set:
    """The keys of the scenes that exist now."""
    return {scene_key(s) for s in bpy.data.scenes}


def state(scene) -> Optional[LiveState]:
    """The scene's last state, or None if Lixel never computed for it."""
    return _states.get(scene_key(scene))


def local_camera(context):
    """The Local Camera of the context's 3D view (View sidebar > View > Local Camera), which F12 there renders
    with (``RenderEngine.camera_override``), or None."""
    space = getattr(context, "space_data", None)
    if space is None or space.type != "VIEW_3D" or not space.use_local_camera:
        return None
    return space.camera


def follow(scene, camera) -> bool:
    """Make the scene's state follow ``camera`` (a 3D view's :func:`local_camera`; None: the scene's camera), as
    the view it is drawn or operated in renders. True when that changed the camera (its view needs describing
    again). Two 3D views of one scene with different cameras make each draw describe its view again."""
    st = _states.get(scene_key(scene))
    if st is None:
        st = _states[scene_key(scene)] = LiveState(scene.name)
    name = camera.name if camera is not None else ""
    if name == st.camera_name:
        return False
    st.camera_name = name
    return True


def _remedy(settings: LixelSettings) -> str:
    """What an empty body's message says before "aim the camera": where the cascade splits only a Custom Visible
    Range, the range may be what holds no receiver."""
    if settings.method != "cascade" or settings.warp.visible_depth_range is None:
        return ";"
    return " within the Visible Range: widen it (Lixel panel > Method > Visible Range) or"


def followed_camera(scene):
    """The camera the scene's state describes: the Local Camera it follows (:func:`follow`) while the scene holds
    it, else the scene's (``render_camera``)."""
    st = _states.get(scene_key(scene))
    camera = scene.objects.get(st.camera_name) if st is not None and st.camera_name else None
    return camera if camera is not None and camera.type == "CAMERA" else render_camera(scene)


def states() -> tuple:
    """Every state held (deleted scenes' ones until the next :func:`update`)."""
    return tuple(_states.values())


def clear() -> None:
    """Forget every scene's state and the pending refinement (file load, unregister)."""
    cancel_refinement()
    _states.clear()


def scene_settings(scene) -> LixelSettings:
    """The scene's ``LixelSettings`` (``scene.lixel`` when the add-on is registered,
    else the defaults)."""
    props = getattr(scene, "lixel", None)
    return props.to_settings() if props is not None else LixelSettings()


def _same(a, b) -> bool:
    """Equality of plain warp inputs (dataclasses holding numpy arrays)."""
    if a is b:
        return True
    if a is None or b is None:
        return False
    if type(a) is not type(b):
        return False
    for k, va in vars(a).items():
        vb = getattr(b, k)
        if isinstance(va, np.ndarray) or isinstance(vb, np.ndarray):
            if va is None or vb is None or np.shape(va) != np.shape(vb) or not np.array_equal(va, vb):
                return False
        elif va != vb:
            return False
    return True


def resolve_method(method: str) -> tuple[str, str]:
    """(method to run, note). A method the warp core does not offer yet runs as
    uniform, with a note saying so."""
    if method in METHODS:
        return method, ""
    return "uniform", f"method '{method}' is not available in this build; showing 'uniform' instead"


@one_blas_thread()
def update(scene, depsgraph=None, changed=None, active=None, settings: Optional[LixelSettings] = None,
           camera=None, light_obj=None, moving: bool = False) -> LiveState:
    """Recompute the scene's Lixel state. ``changed``: a subset of ``INPUTS``
    known to have changed (None: check everything). ``settings`` overrides the
    scene's (scripts); ``camera``/``light_obj`` override the scene's choice.
    ``moving``: the view is changing (the live handlers): an adaptive cascade
    takes the λ splits (``provisional``); otherwise a provisional setup is
    recomputed in full.
    Errors (no camera, no light, no mesh, empty B, and anything unexpected) are
    kept in ``state.error`` with a message for the user; they never raise."""
    for key in _states.keys() - living_scene_keys():   # deleted scenes
        del _states[key]
    st = _states.get(scene_key(scene))
    if st is None:
        st = _states[scene_key(scene)] = LiveState(scene.name)
    st.scene_name = scene.name
    todo = set(INPUTS) if changed is None else set(changed)
    if depsgraph is None and (todo or None in (st.view, st.light, st.bounds)):
        depsgraph = evaluated_depsgraph(scene)    # (view_layers[0].depsgraph of a scene not shown: Blender crashed)
    timings: dict[str, float] = {}
    recomputed = []
    light_notes_before = st.light_notes

    def timed(name, fn, *args, **kw):
        t0 = time.perf_counter()
        try:
            return fn(*args, **kw)
        finally:
            timings[name] = (time.perf_counter() - t0) * 1000.0

    try:
        new_settings = settings if settings is not None else timed("settings", scene_settings, scene)
        view = st.view
        cam = camera if camera is not None else followed_camera(scene)
        if "view" in todo or view is None:
            view = timed("describe view", describe_view, cam, depsgraph, scene)
        check_visible_range(view, new_settings, getattr(cam, "name", ""), scene)   # (as the settings change too)
        light = st.light
        lob = None
        if "light" in todo or light is None:
            lob = pick_light(scene, depsgraph, active, chosen=light_obj)
            light = timed("describe light", describe_light, lob, depsgraph, scene)
            off = shadow_off(lob, depsgraph)   # its pictures are unshadowed, as F12's (renders.as_rendered)
            st.light_name, st.light_pointer = lob.name, lob.as_pointer()
            st.light_notes = (*light_notes(lob, depsgraph), *([off[0].upper() + off[1:]] if off else ()))
        bounds, instances = st.bounds, st.instances
        if "bounds" in todo or bounds is None:
            bounds, instances = timed("describe bounds", scene_bounds, depsgraph)
            if len(bounds.receivers) == 0:
                raise WarpError(f"Scene '{scene.name}' {NO_FACES}: add geometry to cast and receive shadows")
        if todo:   # any change may change a note (a world, a second light, a material): gathered here, not per redraw
            if lob is None:   # the light described before, unless it is no longer the scene's
                lob = light_obj if light_obj is not None else scene.objects.get(st.light_name)
                if lob is None or lob.type != "LIGHT":
                    lob = pick_light(scene, depsgraph, active)
            st.notes = tuple(timed("notes", scene_notes, scene, depsgraph, lob, cam, view, bounds, instances))
    except Exception as exc:  # noqa: BLE001 - every caller gets the message in state.error
        st.notes = ()
        return _fail(st, user_message(exc, f"describing scene '{scene.name}'"), timings)

    inputs_changed = not (_same(view, st.view) and _same(light, st.light) and _same(bounds, st.bounds))
    settings_changed = new_settings != st.settings
    refocused = st.settings is None or st.settings.warp.focus != new_settings.warp.focus
    st.view, st.light, st.bounds, st.instances, st.settings = view, light, bounds, instances, new_settings
    if (not inputs_changed and not settings_changed and st.setup is not None and not st.error
            and (moving or not st.provisional) and st.light_notes == light_notes_before):   # Shadow off: new picture
        st.timings, st.recomputed = timings, ()
        return st
    try:
        body = st.body
        if inputs_changed or refocused or body is None:
            # focused as the settings say: on the visible region (a coarse ray cast against the boxes)
            body = timed("B", focused_body, view, light, bounds, new_settings.warp)
            recomputed.append("B")
        method, note = resolve_method(new_settings.method)
        provisional = moving and method == "cascade" and adaptive_splits(new_settings.warp)
        options = dataclasses.replace(new_settings.warp, cascade_adaptive=False) if provisional else new_settings.warp
        setup = timed("warp", compute, method, view, light, bounds, options, body=body)
        named_in_notes(setup, body, instances, scene)
        recomputed.append("setup")
        geometry = timed("overlay geometry", overlay_geometry, view, setup, body.faces)
        recomputed.append("overlays")
        footprint = timed("footprint", footprint_estimate, setup, view, light, _r_sample(body))
    except EmptyBodyError as exc:   # the core's words ("the camera sees no shadow receiver"), with names and a remedy
        st.body = None
        cam = camera if camera is not None else followed_camera(scene)
        _fail(st, f"Camera '{getattr(cam, 'name', '')}' and light '{st.light_name}' leave Lixel nothing to shadow: "
                  f"{exc}{_remedy(new_settings)} aim the camera (or the light) at the objects that receive shadows",
              timings)
        st.empty_body = str(exc)
        return st
    except Exception as exc:  # noqa: BLE001 - WarpError or a bug: a message either way
        st.body = None
        return _fail(st, user_message(exc, f"computing Lixel's setup for scene '{scene.name}'"), timings)
    note = "; ".join(n for n in (note, *st.light_notes) if n)
    st.body, st.setup, st.method_used, st.note, st.error, st.empty_body = body, setup, method, note, "", ""
    st.provisional = provisional
    st.geometry, st.footprint = geometry, footprint
    st.timings, st.recomputed = timings, tuple(recomputed)
    st.generation += 1
    log.debug("Lixel: %s recomputed %s in %.1f ms", scene.name, recomputed, st.total_ms())
    return st


def named_in_notes(setup, body, instances, scene) -> None:
    """The setup's notes with the receivers and planes of interest the core names by index named as the user knows
    them: the object whose bounds a receiver is, the plane as the panel lists it (``LixelPlane.label``)."""
    name_receivers(setup.diagnostics, body,
                   lambda k: f"object '{instances.owners[instances.owner_ids[instances.receiver_ids[k]]]}'")
    planes = getattr(getattr(scene, "lixel", None), "planes", ())
    name_in_notes(setup.diagnostics, PLANE_OPTION,
                  lambda i: f"plane of interest '{planes[i].label(i)}'" if i < len(planes) else f"planes[{i}]")


def _r_sample(body) -> np.ndarray:
    """Points over R (the visible part of B): its vertices and points between
    them and its centroid."""
    v = np.asarray(body.visible_vertices, dtype=np.float64)
    if len(v) == 0:
        return v
    c = v.mean(axis=0)
    return np.concatenate([v, c[None], 0.5 * (v + c), 0.25 * v + 0.75 * c])


def refine() -> list:
    """Recompute every provisional state, of a scene that exists and has live updates on, with the user's
    settings (the inputs it was moved to; nothing is described again): each is then what a fresh full
    :func:`update` gives. The states refined."""
    refined = []
    for scene in bpy.data.scenes:
        st = _states.get(scene_key(scene))
        props = getattr(scene, "lixel", None)
        if st is not None and st.provisional and (props is None or props.live_update):
            refined.append(update(scene, changed=()))
    return refined


_after_refine: list = []
"""What :func:`refine_after_rest` calls when it refined something (the overlays' redraw)."""


def refine_when_resting(then=None) -> None:
    """Arm the one refinement (a ``bpy.app.timers`` timer, :data:`REST_S` from now; an armed one starts again):
    :func:`refine`, then ``then()``."""
    cancel_refinement()
    _after_refine[:] = [then] if then is not None else []
    bpy.app.timers.register(refine_after_rest, first_interval=REST_S)


def refinement_pending() -> bool:
    return bpy.app.timers.is_registered(refine_after_rest)


def cancel_refinement() -> None:
    """Unregister the refinement timer, if armed (file load, unregister)."""
    if bpy.app.timers.is_registered(refine_after_rest):
        bpy.app.timers.unregister(refine_after_rest)


@guarded_callback("refining Lixel's cascade after the view rested")
def refine_after_rest():
    """The timer: the view rested; refine, redraw, and do not run again. It touches only scenes that exist
    (``bpy.data.scenes``), never one it kept."""
    if refine():
        for then in _after_refine:
            then()
    return None


def _fail(st: LiveState, message: str, timings: dict) -> LiveState:
    st.error, st.empty_body = message, ""
    st.setup = None
    st.provisional = False
    st.geometry = None
    st.footprint = None
    st.timings = timings
    st.recomputed = ()
    st.generation += 1
    return st


def readouts(st: Optional[LiveState]) -> list[tuple[str, str]]:
    """(label, value) pairs for the panel: θ, γ, n_opt or λ, B's vertex count,
    maps, footprint, timings; lengths in the scene's units (:func:`length_text`)."""
    if st is None:
        return []
    if st.setup is None:
        return [("Error", st.error or "not computed")]
    import math
    d = st.setup.diagnostics
    scene = bpy.data.scenes.get(st.scene_name)

    def span(near, far) -> str:
        return f"{length_text(near, scene)}–{length_text(far, scene)}"
    rows = [("Method", st.method_used)]
    rows.append(("θ", "—" if d.theta is None else f"{math.degrees(d.theta):.1f}°"))
    rows.append(("γ", "—" if d.gamma is None else f"{math.degrees(d.gamma):.1f}°"))
    if d.n_opt is not None:
        rows.append(("n_opt", length_text(d.n_opt, scene)))   # a distance (the warp's centre from its near plane)
    if d.lam is not None:
        rows.append(("λ", f"{d.lam:.4g}"))
    if st.body is not None:
        focus = st.body.focus
        if st.body.visible is not None:
            near, far = st.body.visible.depth_range
            focus += f", depth {span(near, far)}"
        rows.append(("Focus", focus))
    rows.append(("B vertices", str(len(d.body_vertices))))
    if "splits" in d.extra:              # a cascade: each split's depths, warp and predicted error
        z, warps, errors = d.extra["splits"], d.extra["split_warps"], d.extra["split_predicted_error"]
        for i, (warp, error) in enumerate(zip(warps, errors)):
            rows.append((f"Split {i}", f"{span(z[i], z[i + 1])}, {warp}, predicted {error:.3g}" if warp
                         else f"{span(z[i], z[i + 1])}, nothing visible"))
        rows.append(("Predicted max", f"{d.extra['predicted_max_error']:.3g} (Lloyd, {d.extra['split_scheme']} splits)"))
        if st.provisional:               # a moving view's: refine_when_resting
            rows.append(("Splits", "PSSM λ while moving; refining" if refinement_pending() else
                         "PSSM λ while moving; live updates paused: Refresh for the adaptive splits"))
    rows.append(("Maps", f"{len(st.setup.maps)}  ({', '.join(m.role for m in st.setup.maps)})"))
    if st.footprint is not None:
        rows.append(("Texel footprint", f"median {st.footprint['median']:.3g} px, max {st.footprint['max']:.3g} px"))
    else:
        rows.append(("Texel footprint", "—"))
    fallbacks, notes = fallbacks_and_notes(d)
    rows += [("Fallback", f"{what}: {why}") for what, why in fallbacks]
    rows += [("Note", f"{what}: {why}") for what, why in notes]
    rows.append(("Last update", f"{st.total_ms():.1f} ms ({', '.join(st.recomputed) or 'nothing changed'})"))
    for k, v in st.timings.items():
        rows.append((f"  {k}", f"{v:.2f} ms"))
    return rows


def compare_methods(st: LiveState, methods=None) -> list[dict]:
    """Every available method on the state's inputs (B shared): one row per
    method with θ, γ, n_opt, λ, map count, footprint statistics, time, or the
    error. ``st`` must hold a computed setup."""
    if st.body is None:
        raise WarpError(st.error or "nothing computed yet")
    rows = []
    for name in (methods or list(METHODS)):
        row: dict = {"method": name}
        t0 = time.perf_counter()
        try:
            setup = compute(name, st.view, st.light, st.bounds, st.settings.warp, body=st.body)
        except WarpError as exc:
            row["error"] = str(exc)
            rows.append(row)
            continue
        row["warp_ms"] = (time.perf_counter() - t0) * 1000.0
        named_in_notes(setup, st.body, st.instances, bpy.data.scenes.get(st.scene_name))
        d = setup.diagnostics
        fallbacks, notes = fallbacks_and_notes(d)
        row.update(theta=d.theta, gamma=d.gamma, n_opt=d.n_opt, lam=d.lam, maps=len(setup.maps),
                   fallbacks=[f"{w}: {r}" for w, r in fallbacks], notes=[f"{w}: {r}" for w, r in notes])
        fp = footprint_estimate(setup, st.view, st.light, _r_sample(st.body))
        row["footprint_median_px"] = None if fp is None else fp["median"]
        row["footprint_max_px"] = None if fp is None else fp["max"]
        row["setup"] = setup
        rows.append(row)
    return rows


def comparison_table(rows: list[dict], scene=None) -> str:
    """The comparison as aligned text (for a Text datablock or a terminal); n_opt, a distance, in ``scene``'s units
    (:func:`length_text`)."""
    import math

    def deg(v):
        return "—" if v is None else f"{math.degrees(v):6.1f}°"

    def num(v, text="{:.4g}".format):
        return "—" if v is None else text(v)

    lines = [f"{'method':<14} {'θ':>7} {'γ':>7} {'n_opt':>9} {'λ':>9} {'maps':>4} "
             f"{'texel px (median)':>18} {'(max)':>9} {'ms':>7}"]
    for r in rows:
        if "error" in r:
            lines.append(f"{r['method']:<14} error: {r['error']}")
            continue
        n_opt = num(r['n_opt'], lambda v: length_text(v, scene))
        lines.append(f"{r['method']:<14} {deg(r['theta']):>7} {deg(r['gamma']):>7} {n_opt:>9} "
                     f"{num(r['lam']):>9} {r['maps']:>4} {num(r['footprint_median_px'], '{:.3g}'.format):>18} "
                     f"{num(r['footprint_max_px'], '{:.3g}'.format):>9} {r['warp_ms']:7.2f}")
    return "\n".join(lines)
