"""The speed-against-error run: for each scene, ground truth, every method at
every map size (GPU pipeline), the peers (EEVEE, Cycles), metrics and the
physical limit. :func:`run` returns plain data; ``figures`` and ``document``
turn it into the report.
"""
from __future__ import annotations

import math
import shutil
import tempfile
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
SAMPLES = ROOT / "sample_blends"


@dataclass
class Options:
    """What to run. ``scenes``: names of sample scenes (or paths to .blend files,
    or "tiny"); ``methods``: warp methods; ``sizes``: shadow-map sides in texels
    (the texel budget, split among a method's maps)."""

    scenes: list
    methods: list
    sizes: list
    resolution: tuple = (640, 360)
    frames: int = 6
    peers: tuple = ("eevee", "cycles")
    eevee_samples: int = 4
    cycles_samples: int = 1
    band_radius: int = 2
    out: Path = ROOT / "out"
    quick: bool = False


def quick_defaults() -> dict:
    return dict(resolution=(240, 135), frames=3, eevee_samples=1)


def full_defaults() -> dict:
    return dict(resolution=(640, 360), frames=6, eevee_samples=16)


DEFAULT_SIZES = (512, 1024, 2048, 4096)
QUICK_SIZES = (512, 2048)


# --------------------------------------------------------------------------- helpers

class Progress:
    def __init__(self, log: Callable[[str], None] = print):
        self.t0 = time.perf_counter()
        self.log = log

    def __call__(self, msg: str) -> None:
        self.log(f"[{time.perf_counter() - self.t0:6.1f}s] {msg}")


def scene_path(name: str, workdir: Path, progress) -> Path:
    """The .blend of a scene name (built if missing), or the path given."""
    p = Path(name)
    if p.suffix == ".blend":
        if not p.exists():
            raise FileNotFoundError(f"no such .blend file: {p}")
        return p
    from sample_blends import build as builder, scenes
    if name == "tiny":
        target = workdir / "tiny.blend"
        if not target.exists():
            builder.build(["tiny"], workdir, log=progress)
        return target
    if name not in scenes.BUILDERS:
        raise ValueError(f"unknown scene {name!r}; choose from {', '.join(scenes.BUILDERS)}, tiny, or a .blend path")
    target = SAMPLES / f"{name}.blend"
    if not target.exists():
        builder.build([name], SAMPLES, log=progress)
    return target


def shaded(normals, light, shadow, hit, ambient=0.08) -> np.ndarray:
    """A grey picture of direct diffuse light (N·L) times visibility, for side-by-side images."""
    h, w = hit.shape
    n = normals.reshape(-1, 3)
    if light.is_directional:
        to_l = np.broadcast_to(-light.direction, n.shape)
        ndl = np.clip(np.einsum("ij,ij->i", n, to_l), 0, 1).reshape(h, w)
    else:
        ndl = np.ones((h, w)) * 0.8
    img = np.where(hit, ambient + (1 - ambient) * ndl * (~shadow), 0.0)
    return img


def comparable_mask(gt, result, tol_rel=2e-3) -> np.ndarray:
    """Pixels where the pipeline shows the same surface point as the ray caster
    (silhouette pixels where rasterization and ray casting disagree are left out)."""
    wp = result["world_position"].astype(np.float64)
    d = np.linalg.norm(wp - gt.points, axis=2)
    depth = np.linalg.norm(gt.points - gt.camera, axis=2)
    return gt.valid & result["covered"] & np.isfinite(d) & (d <= tol_rel * depth + 1e-6)


# --------------------------------------------------------------------------- one scene

def run_scene(name: str, opts: Options, progress, workdir: Path) -> dict:
    import bpy
    from addon.measure import classify, flicker, footprint_stats, lloyd, setup_footprints
    from addon.measure.footprint import perspective_footprints
    from addon.scene.describe import describe_scene, pick_light
    from addon.scene.geometry import GeometryCache
    from addon.settings import ShadowSettings
    from addon.warp import WarpOptions, compute
    from . import ground_truth as G, peers as P

    out: dict = {"name": name, "methods": [], "peers": [], "status": "ok"}
    path = scene_path(name, workdir, progress)
    bpy.ops.wm.open_mainfile(filepath=str(path))
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = opts.resolution
    scene.render.resolution_percentage = 100
    frames = list(range(scene.frame_start, scene.frame_start + max(1, opts.frames)))
    frames = [f for f in frames if f <= max(scene.frame_end, scene.frame_start)] or [scene.frame_start]
    out["frames"] = frames
    out["resolution"] = list(opts.resolution)

    scene.frame_set(frames[0])
    dg = bpy.context.evaluated_depsgraph_get()
    cache = GeometryCache()
    geometry = cache.update(dg)
    tris = G.world_triangles(geometry)
    t = time.perf_counter()
    bvh = G.build_bvh(tris)
    out["triangles"] = len(tris)
    out["instances"] = len(geometry.instances)
    progress(f"{name}: {len(tris):,} triangles in {len(geometry.instances):,} instances, BVH {time.perf_counter() - t:.1f}s")

    # ground truth per frame (the camera moves; the scene does not)
    gts, views = [], []
    for f in frames:
        scene.frame_set(f)
        dg = bpy.context.evaluated_depsgraph_get()
        view, light, bounds = describe_scene(scene, dg)
        gt = G.ground_truth(view, light, bvh, bounds.scale())
        gts.append(gt)
        views.append((view, light, bounds))
    view, light, bounds = views[0]
    gt = gts[0]
    out["ground_truth"] = {"valid_pixels": int(gt.valid.sum()), "shadow_fraction": float(gt.shadow[gt.valid].mean()) if gt.valid.any() else 0.0,
                           "seconds_per_frame": float(np.mean([sum(g.timings.values()) for g in gts]))}
    out["light"] = light.type
    out["view"] = {"fov_x_deg": math.degrees(view.fov_x), "fov_y_deg": math.degrees(view.fov_y),
                   "near": view.near, "far": view.far}
    progress(f"{name}: ground truth for {len(frames)} frame(s), {out['ground_truth']['seconds_per_frame']:.2f}s each; "
             f"{100 * out['ground_truth']['shadow_fraction']:.1f}% of counted pixels in shadow")
    try:
        out["n_min"] = lloyd.n_min(view, light)
    except ValueError as exc:
        out["n_min"] = None
        out["n_min_reason"] = str(exc)
    images = {"truth": shaded(gt.normals, light, gt.shadow, gt.hit), "truth_shadow": gt.shadow,
              "valid": gt.valid, "hit": gt.hit}
    out["_images"] = images

    # --- Lixel methods through the GPU pipeline
    gpu_error = None
    try:
        from addon.gpu.context import ensure_gpu_context
        from addon.gpu.pipeline import render_shadows
        ensure_gpu_context()
    except Exception as exc:  # noqa: BLE001 - every method is then reported failed with this reason
        gpu_error = f"GPU pipeline unavailable: {exc}"
    shadow_settings = ShadowSettings(pcf_kernel=1)
    for method in opts.methods:
        if not gpu_error:
            # warm-up: shader variants, uploads and first-call costs are not part of any time below
            try:
                warm = compute(method, view, light, bounds, WarpOptions(shadow_map_size=(256, 256)))
                render_shadows(view, light, warm, geometry, shadow_settings, opts.resolution, read_maps=False)
            except Exception:  # noqa: BLE001 - the measured runs below report their own failures
                pass
        for size in opts.sizes:
            rec = {"method": method, "size": int(size), "status": "ok"}
            out["methods"].append(rec)
            if gpu_error:
                rec.update(status="failed", reason=gpu_error)
                continue
            try:
                states, valids = [], []
                for k in range(len(frames)):
                    v, l, b = views[k]
                    t0 = time.perf_counter()
                    setup = compute(method, v, l, b, WarpOptions(shadow_map_size=(int(size), int(size))))
                    t_setup = time.perf_counter() - t0
                    res = render_shadows(v, l, setup, geometry, shadow_settings, opts.resolution, read_maps=(k == 0))
                    sh = res["shadow_raw"] >= 0.5
                    comp = comparable_mask(gts[k], res)
                    states.append(sh)
                    valids.append(comp)
                    if k == 0:
                        timings = {"cpu_setup": t_setup, **{s: float(x) for s, x in res["timings"].items()}}
                        errs = classify(sh, gt.shadow, comp, opts.band_radius)
                        fp, _ = setup_footprints(view, setup, gt.points[gt.valid], gt.normals[gt.valid])
                        fp_img = np.full(gt.shape, np.nan)
                        fp_img[gt.valid] = fp
                        stats = footprint_stats(fp)
                        texels = float(sum(int(m.size[0]) * int(m.size[1]) for m in setup.maps))
                        rec.update(
                            maps=[{"role": m.role, "size": list(m.size)} for m in setup.maps],
                            texels=texels, timings=timings,
                            total_ms=1000 * (timings["cpu_setup"] + timings.get("depth_pass", 0) + timings.get("shading", 0)),
                            errors=errs.to_json(), footprint=stats.to_json(),
                            excluded_pixels=int((gt.valid & ~comp).sum()),
                            fallbacks=[list(x) for x in setup.diagnostics.fallbacks],
                        )
                        persp = footprint_stats(perspective_footprints(view, light, setup, gt.points[gt.valid]))
                        rec["perspective_footprint"] = persp.to_json()
                        if out.get("n_min"):
                            mm = lloyd.m_min(out["n_min"], texels)
                            rec["m_min"] = mm
                            rec["max_over_limit"] = persp.max / mm if mm > 0 else None
                        rec["_images"] = {"render": res["combined"][..., 0], "shadow": sh, "comparable": comp,
                                          "footprint": fp_img, "maps": res["shadow_maps"][:4],
                                          "map_roles": [m.role for m in setup.maps][:4]}
                if len(frames) > 1:
                    truth = np.stack([g.shadow for g in gts])
                    vmask = np.stack(valids)
                    rec["flicker"] = flicker(np.stack(states), truth, vmask).to_json()
                progress(f"{name}: {method} @ {size}: {100 * rec['errors']['error_rate']:.2f}% wrong, "
                         f"{rec['total_ms']:.0f} ms, footprint max {rec['footprint']['max']:.2f}")
            except Exception as exc:  # noqa: BLE001 - a failed method is reported, never fatal
                rec.clear()
                rec.update(method=method, size=int(size), status="failed", reason=f"{type(exc).__name__}: {exc}")
                rec["trace"] = traceback.format_exc(limit=3)
                progress(f"{name}: {method} @ {size} FAILED: {exc}")

    # --- peers
    scene.frame_set(frames[0])
    light_obj = pick_light(scene, bpy.context.evaluated_depsgraph_get())
    for peer in opts.peers:
        rec = {"method": peer, "status": "ok"}
        out["peers"].append(rec)
        try:
            samples = opts.eevee_samples if peer == "eevee" else opts.cycles_samples
            res = P.render_shadow_term(scene, light_obj, peer, samples=samples)
            comp = gt.valid & res.lit
            errs = classify(res.shadow, gt.shadow, comp, opts.band_radius)
            rec.update(samples=samples, total_ms=1000 * res.seconds, first_render_ms=1000 * res.seconds_first,
                       errors=errs.to_json(), excluded_pixels=int((gt.valid & ~comp).sum()),
                       _images={"render": res.image / max(float(np.percentile(res.image, 99.5)), 1e-9),
                                "shadow": res.shadow, "comparable": comp})
            progress(f"{name}: {peer}: {100 * errs.error_rate:.2f}% wrong, {res.seconds:.1f}s a render")
        except Exception as exc:  # noqa: BLE001
            rec.update(status="failed", reason=f"{type(exc).__name__}: {exc}")
            progress(f"{name}: {peer} FAILED: {exc}")
    return out


def run(opts: Options, log: Callable[[str], None] = print) -> dict:
    """Run every scene (a scene that fails is recorded, never fatal)."""
    progress = Progress(log)
    workdir = Path(tempfile.mkdtemp(prefix="lixel-report-"))
    import bpy
    result = {"options": {"scenes": list(map(str, opts.scenes)), "methods": list(opts.methods),
                          "sizes": [int(s) for s in opts.sizes], "resolution": list(opts.resolution),
                          "frames": opts.frames, "peers": list(opts.peers), "quick": opts.quick,
                          "eevee_samples": opts.eevee_samples, "cycles_samples": opts.cycles_samples,
                          "band_radius": opts.band_radius},
              "blender": bpy.app.version_string, "scenes": []}
    for name in opts.scenes:
        progress(f"scene {name}")
        try:
            result["scenes"].append(run_scene(str(name), opts, progress, workdir))
        except Exception as exc:  # noqa: BLE001
            progress(f"scene {name} FAILED: {exc}")
            result["scenes"].append({"name": str(name), "status": "failed", "reason": f"{type(exc).__name__}: {exc}",
                                     "trace": traceback.format_exc(limit=4), "methods": [], "peers": []})
    shutil.rmtree(workdir, ignore_errors=True)
    result["seconds"] = time.perf_counter() - progress.t0
    return result
