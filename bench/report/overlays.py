"""Overlay snapshots for the report: Lixel's viewport overlays drawn off-screen
with the viewport's own draw code (``addon.ui.snapshot`` ->
``addon.ui.overlays.draw_scene_overlays``), for each scene:

* the texel grid from the camera, uniform beside the warped method, at a coarse
  map size so that single texels are visible: where the warp puts its texels;
* the footprint heatmap from the camera at a report map size;
* an outside observer's view of the whole setup: the view frustum, the light
  frusta, B, the warp frustum with its projection centre, V_P and B's middle
  vector, over the heatmap on the receivers.

This step only draws (it needs the GPU and the loaded scene); ``figures``
adds the keys and writes the PNGs.
"""
from __future__ import annotations

from dataclasses import dataclass, field

TEXEL_GRID_SIZE = 48
"""Map size of the texel-grid snapshots: coarse, so that one texel spans several pixels."""
HEATMAP_SIZE = 2048
"""Preferred map size of the heatmap snapshots (the report's size nearest to it is used)."""
CAMERA_LONGEST = 560
OBSERVER_SIZE = (960, 600)


@dataclass
class Snapshot:
    """One overlay picture (raw, before its key is added)."""

    kind: str               # "texels", "heatmap", "observer"
    panels: list            # [(title, (h, w, 4) float image)]
    flags: list             # overlays drawn: body, frusta, warp, texels, footprint
    method: str
    size: int
    maps: int
    notes: list = field(default_factory=list)


def _methods(opts) -> tuple[str, list]:
    warped = next((m for m in ("lispsm", "gmnpr", "psm", "plane_optimal", "glpr") if m in opts.methods),
                  opts.methods[0])
    pair = [m for m in dict.fromkeys(("uniform", warped)) if m in opts.methods] or [warped]
    return warped, pair


def snapshots(scene, opts) -> list:
    """Draw the scene's snapshots (a list of :class:`Snapshot`)."""
    import bpy
    from addon.gpu.context import ensure_gpu_context
    from addon.ui import live, overlays, snapshot
    from addon.ui.renders import fit_resolution
    from .lixel import report_settings

    ensure_gpu_context()
    overlays.remove_draw_handlers()   # a new file was loaded: drop the previous scene's batches
    live.clear()
    warped, pair = _methods(opts)
    heat_size = min(opts.sizes, key=lambda s: abs(s - HEATMAP_SIZE))
    dg = bpy.context.evaluated_depsgraph_get()

    def state(method, size):
        st = live.update(scene, dg, settings=report_settings(method, size))
        if not st.ok:
            raise RuntimeError(f"{method} @ {size}: {st.error}")
        return st

    cam_w, cam_h = fit_resolution(opts.resolution, CAMERA_LONGEST)
    shots = []
    for kind, size, flag_names in (("texels", TEXEL_GRID_SIZE, ["texels"]), ("heatmap", heat_size, ["footprint"])):
        panels, maps = [], 0
        for method in pair:
            st = state(method, size)
            vp = snapshot.camera_view_projection(st.view)
            img = snapshot.draw_snapshot(scene, st, snapshot.OverlayFlags.of(flag_names), vp, (cam_w, cam_h))
            panels.append((f"{method}, {size}² ({len(st.setup.maps)} map{'s' if len(st.setup.maps) > 1 else ''})",
                           img))
            maps = max(maps, len(st.setup.maps))
        shots.append(Snapshot(kind, panels, flag_names, warped, size, maps))
    st = state(warped, heat_size)
    w, h = OBSERVER_SIZE
    vp, notes = snapshot.observer_view_projection(st.geometry, st.view, w / h)
    flags = ["body", "frusta", "warp", "footprint"]
    img = snapshot.draw_snapshot(scene, st, snapshot.OverlayFlags.of(flags), vp, (w, h))
    d = st.setup.diagnostics
    if d.warp_frustum_corners is None:
        notes.append(f"{warped} has no bounded warp frustum here (its setup made {len(st.setup.maps)} plain map(s), "
                     f"or P reaches through infinity: its map's volume is drawn around B)")
    shots.append(Snapshot("observer", [(f"{warped}, {heat_size}², seen from outside", img)], flags, warped,
                          heat_size, len(st.setup.maps), notes))
    live.clear()
    overlays.remove_draw_handlers()
    return shots
