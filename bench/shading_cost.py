"""Where the shading pass's time goes, against the trivial full-screen pass of the floor.

    python -m bench.shading_cost [--scenes forest chess] [--repeat 9]

On one frame of each scene (bench.frame's scenes, 1280x720, 2048² lispsm;
camera pre-pass and maps drawn once), in one process, interleaved, as the
median over ``--repeat`` rounds of the process's CPU time (every thread:
llvmpipe's rasterizer threads) and of the wall clock:

* **parts**: the working tree's ``shade_frag.glsl`` cut short after each
  step of its ``main`` (the same pass otherwise: the background pass, the
  depth test against the pre-pass, the colour target with the shadow in
  its alpha):
  a constant output; one surface fetch; the surface and normal decoded;
  + the map selection; + the lighting with no shadow test; the whole pass;
* **settings**: the whole pass with the PCF kernel and the bias mode changed
  (PCF 1 / 2 / 3 / 5, PCF 2 filtering bilinearly with or without its revectorized edges; receiver plane /
  constant / none) and without the Shadow pass read back;
* the floor's **trivial full-screen pass** (``bench.frame.Floor.full_screen``).
"""
from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

_scratch = tempfile.mkdtemp(prefix="lixel-bench-shading-")
os.environ.setdefault("XDG_CACHE_HOME", os.path.join(_scratch, "xdg"))
os.environ.setdefault("BLENDER_USER_RESOURCES", os.path.join(_scratch, "blender-user"))

READ = frozenset({"combined", "shadow_mask"})
"""The engine's default passes: the Combined image and the Shadow."""

CUTS = {
    "constant output": ("  ivec2 px = ivec2(gl_FragCoord.xy);", "  out_color = vec4(1.0);"),
    "one surface fetch": ("  vec4 surface = texelFetch(u_surface, px, 0);", "  out_color = surface;"),
    "surface and normal": ("  float eye_depth = -dot(lixel.eye_row, vec4(P, 1.0));",
                           "  out_color = vec4(N * 0.5 + 0.5, eye_depth);"),
    "+ map selection": ("  vec2 tc = (ndc.xy * 0.5 + 0.5) * vec2(size);",
                        "  out_color = vec4(N.xy * 0.5 + 0.5, tc.x + tc.y, float(index));"),
}
"""Name -> (the line of main() after which the pass stops, what it writes then)."""


def cut_source(src: str, after: str, body: str) -> str:
    at = src.index(after, src.index("void main()")) + len(after)
    return src[:at] + "\n" + body + "\n  return;\n" + src[at:]


def compiled_variants(shaders, variant) -> dict:
    """Shading shaders of ``variant`` built from cut copies of shade_frag.glsl."""
    src = (shaders.SHADER_DIR / "shade_frag.glsl").read_text()
    texts = {name: cut_source(src, *cut) for name, cut in CUTS.items()}
    texts["+ lighting, no shadow test"] = src.replace("    shadow = lixel_shadow(m, P, N, L, hsel);", "    shadow = 0.0;")
    out = {}
    here = shaders.SHADER_DIR
    for name, text in texts.items():
        folder = Path(tempfile.mkdtemp(prefix="lixel-shade-cut-"))
        for f in here.iterdir():
            shutil.copy(f, folder / f.name)
        (folder / "shade_frag.glsl").write_text(text)
        shaders.source.cache_clear()
        shaders.shade_shader.cache_clear()
        shaders.SHADER_DIR = folder
        try:
            out[name] = shaders.shade_shader(variant)
        finally:
            shaders.SHADER_DIR = here
            shaders.source.cache_clear()
            shaders.shade_shader.cache_clear()
    return out


def measure(name: str, repeat: int) -> dict:
    import bpy

    import bench.frame as bf
    from addon.gpu import compose, shaders
    from addon.scene.describe import describe_scene
    from addon.settings import LixelSettings, ShadowSettings
    from addon.warp import WarpOptions

    scene = bf.make_scene(bpy, name)
    scene.render.resolution_x, scene.render.resolution_y = 1280, 720
    scene.render.resolution_percentage = 100
    settings = LixelSettings(method="lispsm", warp=WarpOptions(shadow_map_size=(2048, 2048)))
    dg = bpy.context.evaluated_depsgraph_get()
    frame, setup = bf._lixel_frame(dg, settings)
    _, light, _ = describe_scene(scene, dg, instances=frame.geometry.instances)
    default = ShadowSettings()
    variant = shaders.ShadeVariant(map_count=len(setup.maps), light=light.type, pcf=default.pcf_kernel,
                                   revectorize=default.revectorize, bias=default.bias_mode, footprint=False,
                                   shadow_alpha=True,
                                   linear_z=shaders.agreed(m.depth_row is not None for m in setup.maps),
                                   greater=shaders.agreed(m.depth_test == "GREATER" for m in setup.maps))
    cuts = compiled_variants(shaders, variant)
    build = shaders.shade_shader

    def shade(shadow, read=READ, shader=None):
        if shader is not None:
            shaders.shade_shader = lambda v: shader
        try:
            frame.shade(light, setup, shadow, read=read)
            compose.sync(frame.targets.framebuffer(colors=(frame._shaded["textures"]["color"],)), color=True)
        finally:
            shaders.shade_shader = build

    runs = {f"part: {k}": (lambda s=s: shade(default, shader=s)) for k, s in cuts.items()}
    runs.update({
        f"whole pass (the defaults: PCF {default.pcf_kernel}, receiver plane)": lambda: shade(default),
        "whole pass, no Shadow pass read": lambda: shade(default, frozenset({"combined"})),
        "PCF 1": lambda: shade(ShadowSettings(pcf_kernel=1)),
        "PCF 2 (bilinear), edges revectorized": lambda: shade(ShadowSettings(pcf_kernel=2, revectorize=True)),
        "PCF 3 (box; the default until session 3, 0.5 texel)": lambda: shade(ShadowSettings(pcf_kernel=3, constant_bias=0.5)),
        "PCF 5": lambda: shade(ShadowSettings(pcf_kernel=5)),
        "PCF 2, constant bias": lambda: shade(ShadowSettings(bias_mode="CONSTANT")),
        "PCF 1, no bias": lambda: shade(ShadowSettings(pcf_kernel=1, bias_mode="NONE")),
        "floor: trivial full-screen pass": bf.Floor(frame, setup).full_screen,
    })
    for fn in runs.values():
        fn()
    cpu = {k: [] for k in runs}
    wall = {k: [] for k in runs}
    for _ in range(repeat):
        for k, fn in runs.items():
            c, w = time.process_time(), time.perf_counter()
            fn()
            cpu[k].append(time.process_time() - c)
            wall[k].append(time.perf_counter() - w)
    return {k: (statistics.median(cpu[k]) * 1e3, statistics.median(wall[k]) * 1e3) for k in runs}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.shading_cost", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", nargs="+", default=["forest", "chess"])
    ap.add_argument("--repeat", type=int, default=9)
    args = ap.parse_args(argv)
    import bpy  # noqa: F401 - Blender before mathutils
    from addon.gpu.blas import one_blas_thread
    from addon.gpu.context import ensure_gpu_context
    from addon.render import engine
    engine.register()
    try:
        ensure_gpu_context()
        with one_blas_thread():   # as every frame has it (render_depsgraph)
            for name in args.scenes:
                rows = measure(name, args.repeat)
                print(f"\n== {name}: shading pass, 1280x720, 2048² lispsm (CPU ms, wall ms; medians)")
                for k, (c, w) in rows.items():
                    print(f"  {k:38s} {c:7.1f} {w:8.1f}")
                sys.stdout.flush()
    finally:
        engine.unregister()
    return 0


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    os._exit(code)
