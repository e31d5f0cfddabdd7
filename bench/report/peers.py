"""Blender's own renderers as peers: the shadow term of EEVEE and of Cycles.

The shadow term is the ratio of two renders of the scene with every material
overridden by one grey diffuse material (Lixel's albedo), the scene's black
world and its one light: the render with shadows divided by the render with
the light's shadows switched off (``Light.use_shadow``). A pixel is in shadow
when the ratio is below 0.5.

Timing, like Lixel's (process CPU time and wall clock, ``timing``): a timed
render is ``bpy.ops.render.render`` from its call to the pixels in Blender's
Render Result (memory); nothing is written to a file inside the time (the
result is saved as EXR afterwards, only to read it into numpy). Before the
timed renders, one render with shadows absorbs EEVEE's shader compilation (it
is reported as the first render's time). A point is the median of
``repeats`` renders.

Settings, stated in the report (:func:`stated_settings`):

* Cycles: direct light only (no bounces), one sample, a 0.01 px box filter,
  no light threshold (no Russian roulette on shadow rays): exact for a delta light.
* EEVEE (4.2+: virtual shadow maps): the light is hard (radius/angle 0, no
  jitter, filter radius 0), one sample, no ray tracing or AO. Its shadow maps
  are virtual tile maps of 32 x 32 pages of 256² texels, 8192² texels per
  tile map (one per sun clipmap level, spot, or cube face) at resolution
  100 %; the report sets the scene's shadow resolution scale to size / 8192,
  so at map size ``size`` each of EEVEE's tile maps has at most size² texels.
"""
from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass

import numpy as np

from .timing import Clocks, Timing, load_average, summarise

PEERS = ("eevee", "cycles")
EEVEE_TILEMAP_TEXELS = 32 * 256
"""Texels per side of one EEVEE virtual shadow tile map at resolution scale 1 (SHADOW_TILEMAP_RES x SHADOW_PAGE_RES)."""
MATERIAL_NAME = "Lixel report grey diffuse"
WORLD_NAME = "Lixel report black world"


def eevee_engine_id() -> str:
    import bpy
    return "BLENDER_EEVEE" if bpy.app.version >= (5, 0, 0) else "BLENDER_EEVEE_NEXT"


def eevee_resolution_scale(size: int) -> float:
    """EEVEE's shadow resolution scale that caps each tile map at ``size``² texels."""
    return min(1.0, float(size) / EEVEE_TILEMAP_TEXELS)


def stated_settings(peer: str, samples: int, size=None) -> str:
    if peer == "cycles":
        return f"Cycles CPU, {samples} sample(s), direct light only, 0.01 px box filter, no light threshold"
    scale = eevee_resolution_scale(size) if size else 1.0
    tile = int(round(EEVEE_TILEMAP_TEXELS * scale))
    return (f"EEVEE, {samples} sample(s), virtual shadow maps at resolution scale {100 * scale:.4g} % "
            f"(each tile map at most {tile}² texels), hard light (no jitter, filter radius 0), no ray tracing")


@dataclass
class PeerResult:
    shadow: np.ndarray        # (H, W) bool, row 0 at the bottom
    ratio: np.ndarray         # (H, W) shadowed / unshadowed radiance
    lit: np.ndarray           # (H, W) bool: the unshadowed render has light here (ratio is meaningful)
    image: np.ndarray         # (H, W) the shadowed render's luminance (linear radiance, Lixel's units)
    timing: Timing
    settings: str


def grey_material(albedo: float):
    """One grey, fully rough diffuse material with Lixel's albedo, so that the
    peers' radiance and Lixel's are in the same units and one exposure shows both."""
    from sample_blends.scenes import diffuse_material
    return diffuse_material(MATERIAL_NAME, albedo)


def black_world():
    """A world that emits nothing (its Background node at strength 0, if it has
    nodes): the scene's light is the only light, as in Lixel's frame and the
    ground truth (a new world's default grey background would light the shadows)."""
    import bpy
    world = bpy.data.worlds.get(WORLD_NAME) or bpy.data.worlds.new(WORLD_NAME)
    world.color = (0.0, 0.0, 0.0)
    if getattr(world, "use_nodes", False) and world.node_tree is not None:
        for node in world.node_tree.nodes:
            if node.type == "BACKGROUND":
                node.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
                node.inputs["Strength"].default_value = 0.0
    return world


def _luminance(px: np.ndarray) -> np.ndarray:
    return (0.2126 * px[..., 0] + 0.7152 * px[..., 1] + 0.0722 * px[..., 2]).astype(np.float64)


class PeerSession:
    """Render a scene with one peer; the scene's render settings, the light's
    shadow settings and the view layers' material overrides are restored on exit."""

    def __init__(self, scene, light_obj, peer: str, samples: int, albedo: float):
        if peer not in PEERS:
            raise ValueError(f"unknown peer {peer!r}; choose from {', '.join(PEERS)}")
        self.scene, self.light_obj, self.peer, self.samples, self.albedo = scene, light_obj, peer, samples, albedo
        self.tmp = tempfile.mkdtemp(prefix="lixel-peer-")
        self.open_image = None
        self.first_s = float("nan")

    # --- settings
    def __enter__(self):
        r, ld = self.scene.render, self.light_obj.data
        self._saved = dict(engine=r.engine, fmt=r.image_settings.file_format, depth=r.image_settings.color_depth,
                           filter=r.filter_size, use_shadow=ld.use_shadow, soft=ld.shadow_soft_size,
                           angle=getattr(ld, "angle", None),
                           light_attrs={a: getattr(ld, a) for a in ("use_shadow_jitter", "shadow_filter_radius")
                                        if hasattr(ld, a)},
                           eevee_scale=getattr(self.scene.eevee, "shadow_resolution_scale", None),
                           overrides=[vl.material_override for vl in self.scene.view_layers])
        mat = grey_material(self.albedo)
        for vl in self.scene.view_layers:
            vl.material_override = mat
        self._saved["world"] = self.scene.world
        self.scene.world = black_world()
        r.image_settings.file_format = "OPEN_EXR"
        r.image_settings.color_depth = "32"
        r.filter_size = 0.01
        ld.shadow_soft_size = 0.0
        if ld.type == "SUN":
            ld.angle = 0.0
        for attr, val in (("use_shadow_jitter", False), ("shadow_filter_radius", 0.0)):
            if hasattr(ld, attr):
                setattr(ld, attr, val)
        if self.peer == "cycles":
            self._cycles()
        else:
            self._eevee()
        return self

    def __exit__(self, *exc):
        s, r, ld = self._saved, self.scene.render, self.light_obj.data
        r.engine = s["engine"]
        r.image_settings.file_format = s["fmt"]
        r.image_settings.color_depth = s["depth"]
        r.filter_size = s["filter"]
        ld.use_shadow = s["use_shadow"]
        ld.shadow_soft_size = s["soft"]
        if s["angle"] is not None and ld.type == "SUN":
            ld.angle = s["angle"]
        for attr, val in s["light_attrs"].items():
            setattr(ld, attr, val)
        if s["eevee_scale"] is not None:
            self.scene.eevee.shadow_resolution_scale = s["eevee_scale"]
        for vl, mat in zip(self.scene.view_layers, s["overrides"]):
            vl.material_override = mat
        self.scene.world = s["world"]
        for f in os.listdir(self.tmp):
            os.remove(os.path.join(self.tmp, f))
        os.rmdir(self.tmp)
        return False

    def _cycles(self):
        r = self.scene.render
        r.engine = "CYCLES"
        c = self.scene.cycles
        c.device = "CPU"
        c.samples = max(1, int(self.samples))
        c.use_adaptive_sampling = False
        c.use_denoising = False
        # no Russian roulette on dim light samples: the default light threshold (0.01)
        # ends shadow rays at random where the light is weak (a noisy shadow term under a spot)
        c.light_sampling_threshold = 0.0
        c.max_bounces = 0
        c.diffuse_bounces = 0
        c.caustics_reflective = c.caustics_refractive = False
        c.pixel_filter_type = "BOX"
        c.filter_width = 0.01

    def _eevee(self):
        self.scene.render.engine = eevee_engine_id()
        e = self.scene.eevee
        e.taa_render_samples = max(1, int(self.samples))
        for attr, val in (("use_raytracing", False), ("use_gtao", False), ("use_bloom", False),
                          ("use_shadows", True), ("use_soft_shadows", False), ("use_shadow_jitter_viewport", False)):
            if hasattr(e, attr):
                setattr(e, attr, val)

    # --- renders
    def _render(self) -> tuple[float, float]:
        """One render: (wall seconds, process CPU seconds) from the call to the Render Result."""
        import bpy
        start = Clocks.now()
        bpy.ops.render.render(write_still=False, scene=self.scene.name)
        return start.since()

    def _read(self) -> np.ndarray:
        """The last Render Result as (H, W) luminance (saved to EXR outside any timing)."""
        import bpy
        from addon.ui.renders import load_pixels
        path = os.path.join(self.tmp, "result.exr")
        bpy.data.images["Render Result"].save_render(path, scene=self.scene)
        px = load_pixels(path)
        os.remove(path)
        return _luminance(px)

    def reference(self) -> None:
        """The render without shadows (the ratio's denominator), then one render
        with shadows that absorbs the shader compilation (its time: ``first_s``)."""
        self.light_obj.data.use_shadow = False
        self._render()
        self.open_image = self._read()
        self.light_obj.data.use_shadow = True
        self.first_s = self._render()[0]

    def shadowed(self, repeats: int, size=None) -> PeerResult:
        """Median of ``repeats`` timed renders with shadows (EEVEE: tile maps capped at ``size``²)."""
        if self.open_image is None:
            self.reference()
        if self.peer == "eevee" and size:
            self.scene.eevee.shadow_resolution_scale = eevee_resolution_scale(size)
        self.light_obj.data.use_shadow = True
        load = load_average()
        runs = [self._render() for _ in range(max(1, int(repeats)))]
        load = 0.5 * (load + load_average())
        shadowed = self._read()
        open_ = self.open_image
        lit = open_ > 1e-4 * max(float(open_.max()), 1e-12)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(lit, shadowed / np.where(lit, open_, 1.0), 1.0)
        return PeerResult(shadow=lit & (ratio < 0.5), ratio=ratio, lit=lit, image=shadowed,
                          timing=summarise(runs, first_s=self.first_s, load=load),
                          settings=stated_settings(self.peer, self.samples, size if self.peer == "eevee" else None))
