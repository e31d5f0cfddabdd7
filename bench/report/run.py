"""The speed-against-error run: for each scene, ground truth, every method at
every map size through Lixel's render engine frame, the peers (EEVEE, Cycles),
metrics, the physical limit and the overlay snapshots. :func:`run` returns
plain data; ``figures`` and ``document`` turn it into the report.
"""
from __future__ import annotations

import math
import shutil
import tempfile
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from addon.settings import MAX_MAP_SIZE  # the longest map side (warp.types.MAX_MAP_SIDE); __main__ reads it here

from .progress import Progress, Step, quiet_blender

ROOT = Path(__file__).resolve().parents[2]
SAMPLES = ROOT / "sample_blends"


@dataclass
class Options:
    """What to run. ``scenes``: names of sample scenes (or paths to .blend files,
    or "tiny"); ``methods``: warp methods; ``sizes``: shadow-map sides in texels
    (the texel budget, split among a method's maps). ``repeats``: timed frames
    per Lixel point (median, min, max); ``peer_repeats``: timed renders per peer
    point; ``eevee_sizes``: the map sizes EEVEE runs at (default: every size)."""

    scenes: list
    methods: list
    sizes: list
    resolution: tuple = (640, 360)
    frames: int = 4
    peers: tuple = ("eevee", "cycles")
    eevee_samples: int = 1
    cycles_samples: int = 1
    repeats: int = 7
    peer_repeats: int = 3
    eevee_sizes: Optional[list] = None
    band_radius: int = 2
    overlays: bool = True
    out: Path = ROOT / "out"
    quick: bool = False

    def eevee_at(self) -> list:
        sizes = self.eevee_sizes if self.eevee_sizes is not None else self.sizes
        return [s for s in sizes if s <= MAX_MAP_SIZE]


def quick_defaults() -> dict:
    return dict(resolution=(240, 135), frames=2, repeats=7, peer_repeats=3)


def full_defaults() -> dict:
    return dict(resolution=(640, 360), frames=4, repeats=7, peer_repeats=3)


DEFAULT_SIZES = (512, 1024, 2048, 4096)
QUICK_SIZES = (512, 2048)

GUESS_S = {"scene": 4.0, "method": 1.0, "timing": 1.5, "eevee reference": 20.0, "eevee": 8.0,
           "cycles reference": 1.0, "cycles": 0.6, "overlays": 4.0, "figures": 4.0}
"""Seconds each kind of step takes before one has been timed (the estimate of time left)."""


# --------------------------------------------------------------------------- what to run

def scene_names() -> list:
    from sample_blends.scenes import BUILDERS
    return list(BUILDERS)


MIN_SIDE = 4
"""The smallest render side Blender takes (``RenderSettings.resolution_x``'s minimum, 4.2 and 5.0): it raised a 3x2
report to 4x4 unasked, and every method failed on "operands could not be broadcast together"."""


def check(opts: Options) -> list:
    """Problems with the options (an empty list when they can run)."""
    from addon.warp import METHODS
    problems = []
    known = scene_names()
    for name in opts.scenes:
        p = Path(str(name))
        if p.suffix == ".blend":
            if not p.is_file():
                problems.append(f"--scene: no such .blend file: {p}")
        elif name not in known and name != "tiny":
            problems.append(f"--scene: unknown scene {name!r}; choose from {', '.join(known)} (or a .blend path)")
    if not opts.scenes:
        problems.append("--scene: no scene given")
    labels = [Path(str(name)).stem for name in opts.scenes]
    if twice := sorted({label for label in labels if labels.count(label) > 1}):
        problems.append(f"--scene: {', '.join(map(repr, twice))} given twice: a scene is named by its file name, "
                        f"and each has one folder of figures in the report; rename one of the .blend files")
    for option, given in (("--methods", opts.methods), ("--sizes", opts.sizes), ("--peers", opts.peers),
                          ("--eevee-sizes", opts.eevee_sizes or ())):
        if twice := sorted({str(v) for v in given if list(given).count(v) > 1}):
            problems.append(f"{option}: {', '.join(map(repr, twice))} given twice: each is measured once")
    bad = [m for m in opts.methods if m not in METHODS]
    if bad or not opts.methods:
        problems.append(f"--methods: unknown {', '.join(map(repr, bad)) or '(none given)'}; "
                        f"choose from {', '.join(METHODS)}")
    if not opts.sizes or any(s < 1 for s in opts.sizes):
        problems.append("--sizes: give positive map sizes in texels per side")
    from .peers import PEERS
    bad = [p for p in opts.peers if p not in PEERS]
    if bad:   # ('' for --peers '': an empty shell variable, which ran no peer without a word)
        problems.append(f"--peers: unknown {', '.join(repr(p) for p in bad if p) or '(none given)'}; "
                        f"choose from {', '.join(PEERS)} or none")
    w, h = opts.resolution
    if not (MIN_SIDE <= w <= 8192 and MIN_SIDE <= h <= 8192):
        problems.append(f"--resolution: {w}x{h} is outside {MIN_SIDE}..8192 pixels per side")
    if opts.eevee_sizes is not None and any(s < 1 for s in opts.eevee_sizes):   # 0 ran EEVEE unmatched, unsaid
        problems.append("--eevee-sizes: give positive map sizes in texels per side")
    for option, value in (("--frames", opts.frames), ("--repeats", opts.repeats),
                          ("--peer-repeats", opts.peer_repeats), ("--eevee-samples", opts.eevee_samples)):
        if value < 1:   # EEVEE rendered 1 sample where the report said 0 or -1
            problems.append(f"{option}: {value} is not at least 1")
    return problems


def plan(opts: Options) -> list:
    """Every step of the run, in order (for the progress counter and the estimate)."""
    steps = []
    for name in map(str, opts.scenes):
        label = Path(name).stem
        steps.append(Step("scene", f"{label}: ground truth", label))
        steps += [Step("method", f"{label}: {m} @ {s}", label) for m in opts.methods for s in opts.sizes]
        steps += [Step("timing", f"{label}: timing round {r + 1}/{opts.repeats}", label) for r in range(opts.repeats)]
        for peer in opts.peers:
            steps.append(Step(f"{peer} reference", f"{label}: {peer} reference renders", label))
            sizes = opts.eevee_at() if peer == "eevee" else [None]
            steps += [Step(peer, f"{label}: {peer}" + (f" @ {s}" if s else ""), label) for s in sizes]
        if opts.overlays:
            steps.append(Step("overlays", f"{label}: overlay snapshots", label))
    steps += [Step("figures", f"{Path(str(n)).stem}: figures", Path(str(n)).stem) for n in opts.scenes]
    return steps


def scene_path(name: str, workdir: Path, log) -> Path:
    """The .blend of a scene name (built if missing), or the path given."""
    p = Path(name)
    if p.suffix == ".blend":
        return p
    from sample_blends import build as builder
    target = (workdir if name == "tiny" else SAMPLES) / f"{name}.blend"
    if not target.exists():
        with quiet_blender():
            builder.build([name], target.parent, log=log)
    return target


# --------------------------------------------------------------------------- helpers

SAME_SURFACE_RAD = 0.05
"""Largest angle between the pipeline's and the ray caster's normals at a pixel showing the same surface: the
pre-pass normal is within about 5e-4 rad of its triangle's, and a non-planar quad that the ray caster's BVH
splits along the other diagonal tilts by up to 1e-2 rad (the terrain sample's ground, 9.6e-3); a box's faces
meet at 90 degrees, a 32-sided cylinder's at 11."""


def comparable_mask(gt, frame) -> np.ndarray:
    """Pixels where the pipeline shows the same surface point as the ray caster: silhouette pixels where
    rasterization and ray casting disagree are left out, and so are crease pixels where both see the same point
    (an edge or corner of a box, within a rasterizer's sub-pixel snapping) but on different faces, whose shadows
    differ (``world_normal``, where the frame has it).
    ``frame``: a ``LixelFrame`` or anything with ``world_position`` and ``covered`` (and optionally
    ``world_normal``) as keys (a render result dict) or attributes."""
    get = frame.get if isinstance(frame, dict) else (lambda k: getattr(frame, k))
    world, covered = np.asarray(get("world_position"), dtype=np.float64), np.asarray(get("covered"), dtype=bool)
    d = np.linalg.norm(world - gt.points, axis=2)
    depth = np.linalg.norm(gt.points - gt.camera, axis=2)
    same = gt.valid & covered & np.isfinite(d) & (d <= 2e-3 * depth + 1e-6)
    normal = frame.get("world_normal") if isinstance(frame, dict) else getattr(frame, "world_normal", None)
    if normal is not None:
        with np.errstate(invalid="ignore"):
            same &= np.abs(np.einsum("ijk,ijk->ij", np.asarray(normal, dtype=np.float64), gt.normals)) \
                >= math.cos(SAME_SURFACE_RAD)
    return same


def diagnostics(setup) -> dict:
    """θ, γ (degrees), n_opt, λ of a setup (None where the method has none)."""
    d = setup.diagnostics

    def deg(x):
        return None if x is None else math.degrees(float(x))
    return {"theta_deg": deg(d.theta), "gamma_deg": deg(d.gamma),
            "n_opt": None if d.n_opt is None else float(d.n_opt),
            "lam": None if d.lam is None else float(d.lam)}


def shading_difference(image, shadow, counted, truth_image, truth_shadow) -> Optional[float]:
    """Median relative difference of a render's radiance from the ground
    truth's over the pixels both call lit: how far "shaded the same way" holds."""
    img = np.asarray(image, dtype=np.float64)
    if img.ndim == 3:
        img = 0.2126 * img[..., 0] + 0.7152 * img[..., 1] + 0.0722 * img[..., 2]
    both = counted & ~shadow & ~truth_shadow & (truth_image > 0)
    if not both.any():
        return None
    return float(np.median(np.abs(img[both] - truth_image[both]) / truth_image[both]))


def exposure(truth_direct: np.ndarray, mask: np.ndarray) -> float:
    """One exposure for every render of a scene: the ground truth's unshadowed
    direct light at its 99th percentile over the counted pixels maps to white."""
    v = truth_direct[mask & (truth_direct > 0)]
    return 1.0 / float(np.percentile(v, 99)) if v.size else 1.0


# --------------------------------------------------------------------------- one scene

@dataclass
class SceneRun:
    """What one scene's steps share."""

    name: str
    opts: Options
    progress: Progress
    scene: object = None
    gts: list = field(default_factory=list)
    views: list = field(default_factory=list)
    frames: list = field(default_factory=list)
    out: dict = field(default_factory=dict)


def run_scene(name: str, opts: Options, progress: Progress, workdir: Path) -> dict:
    import bpy
    from addon.measure import lloyd
    from . import analysis

    label = Path(name).stem
    run = SceneRun(label, opts, progress)
    out = run.out
    out.update(name=label, methods=[], peers=[], status="ok", overlays=[])
    with progress.step("scene", f"{label}: ground truth", label):
        _ground_truth(run, name, workdir)
    gt, (view, light, _bounds) = run.gts[0], run.views[0]
    try:
        out["n_min"] = lloyd.n_min(view, light)
    except ValueError as exc:
        out["n_min"] = None
        out["n_min_reason"] = str(exc)
    lit = analysis.lit_facing(gt, light)
    out["lit_facing_pixels"] = int(lit.sum())
    out["_images"]["lit_facing"] = lit
    out["_images"]["facing"] = analysis.facing(gt, light)

    gpu_error = _start_gpu()
    for method in opts.methods:
        for size in opts.sizes:
            with progress.step("method", f"{label}: {method} @ {size}", label):
                rec = _method(run, method, int(size), lit, gpu_error)
            out["methods"].append(rec)
            _say_method(progress, label, rec)
    _time_methods(run)
    _explain(out)
    run.scene.frame_set(run.frames[0])
    for peer in opts.peers:
        _peer(run, peer)
    if opts.overlays:
        with progress.step("overlays", f"{label}: overlay snapshots", label):
            _overlays(run)
    return out


def _start_gpu() -> Optional[str]:
    try:
        from addon.gpu.context import ensure_gpu_context
        with quiet_blender():
            ensure_gpu_context()
    except Exception as exc:  # noqa: BLE001 - every method is then reported failed with this reason
        return f"GPU pipeline unavailable: {exc}"
    return None


def _ground_truth(run: SceneRun, name: str, workdir: Path) -> None:
    import bpy
    from addon.scene.describe import describe_scene, pick_light
    from addon.scene.geometry import GeometryCache
    from addon.gpu.pipeline import DEFAULT_ALBEDO
    from . import ground_truth as G

    opts, out = run.opts, run.out
    path = scene_path(name, workdir, log=run.progress.log)
    with quiet_blender():
        bpy.ops.wm.open_mainfile(filepath=str(path))
    scene = run.scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = opts.resolution
    scene.render.resolution_percentage = 100
    frames = list(range(scene.frame_start, scene.frame_start + max(1, opts.frames)))
    run.frames = [f for f in frames if f <= max(scene.frame_end, scene.frame_start)] or [scene.frame_start]
    out["frames"] = run.frames
    out["resolution"] = list(opts.resolution)
    scene.frame_set(run.frames[0])
    dg = bpy.context.evaluated_depsgraph_get()
    geometry = GeometryCache().update(dg)
    tris = G.world_triangles(geometry)
    t = time.perf_counter()
    bvh = G.build_bvh(tris)
    out["triangles"], out["instances"] = len(tris), len(geometry.instances)
    out["bvh_seconds"] = time.perf_counter() - t
    for f in run.frames:
        scene.frame_set(f)
        dg = bpy.context.evaluated_depsgraph_get()
        view, light, bounds = describe_scene(scene, dg)
        run.gts.append(G.ground_truth(view, light, bvh, bounds.scale()))
        run.views.append((view, light, bounds))
    scene.frame_set(run.frames[0])
    gt, (view, light, _) = run.gts[0], run.views[0]
    light_obj = pick_light(scene, bpy.context.evaluated_depsgraph_get())
    blend = float(getattr(light_obj.data, "spot_blend", 0.0)) if light.type == "SPOT" else 0.0
    direct = G.direct_light(gt.points, gt.normals, light, DEFAULT_ALBEDO, blend)
    out["exposure"] = exposure(direct, gt.valid)
    out["ground_truth"] = {"valid_pixels": int(gt.valid.sum()),
                           "shadow_fraction": float(gt.shadow[gt.valid].mean()) if gt.valid.any() else 0.0,
                           "seconds_per_frame": float(np.mean([sum(g.timings.values()) for g in run.gts]))}
    out["light"] = light.type
    out["light_name"] = light_obj.name
    out["camera_name"] = scene.camera.name if scene.camera else ""
    out["view"] = {"fov_x_deg": math.degrees(view.fov_x), "fov_y_deg": math.degrees(view.fov_y),
                   "near": view.near, "far": view.far}
    out["_images"] = {"truth": np.where(gt.hit & ~gt.shadow, direct, 0.0), "truth_shadow": gt.shadow,
                      "valid": gt.valid, "hit": gt.hit}
    run.progress.log(f"{run.name}: {len(tris):,} triangles in {len(geometry.instances):,} instances; ground truth "
                     f"{out['ground_truth']['seconds_per_frame']:.2f} s a frame, "
                     f"{100 * out['ground_truth']['shadow_fraction']:.1f} % of counted pixels in shadow")


def _method(run: SceneRun, method: str, size: int, lit: np.ndarray, gpu_error: Optional[str]) -> dict:
    """Render every frame of the animation with one method and size (untimed:
    the timing rounds come after), and measure frame 0 against the truth."""
    import bpy
    from addon.measure import classify, flicker, footprint_stats, lloyd, setup_footprints
    from addon.measure.footprint import perspective_footprints
    from addon.ui.live import fallbacks_and_notes
    from . import analysis
    from .lixel import frame, report_settings

    rec = {"method": method, "size": size, "status": "ok"}
    if gpu_error:
        rec.update(status="failed", reason=gpu_error)
        return rec
    if size > MAX_MAP_SIZE:
        rec.update(status="failed", reason=f"map size {size} exceeds the GPU's {MAX_MAP_SIZE} texels per side")
        return rec
    opts, out, gts = run.opts, run.out, run.gts
    settings = report_settings(method, size)
    try:
        states, valids, stages = [], [], []
        for k, f in enumerate(run.frames):
            run.scene.frame_set(f)
            fr = frame(bpy.context.evaluated_depsgraph_get(), settings, opts.resolution)
            comp = comparable_mask(gts[k], fr)
            states.append(fr.shadow)
            valids.append(comp)
            stages.append(fr.stages)
            if k == 0:
                first = fr
                rec["_first_s"] = fr.seconds  # the point's first frame: shader variants, uploads
        rec["_stages"] = stages[1:] or stages   # the stage times of the warm frames
        gt = gts[0]
        view, light, _ = run.views[0]
        fr, comp = first, valids[0]
        setup = fr.setup
        fp, _ = setup_footprints(view, setup, gt.points[gt.valid], gt.normals[gt.valid])
        fp_img = np.full(gt.shape, np.nan)
        fp_img[gt.valid] = fp
        texels = float(sum(int(m.size[0]) * int(m.size[1]) for m in setup.maps))
        errs = classify(fr.shadow, gt.shadow, comp, opts.band_radius)
        fallbacks, notes = fallbacks_and_notes(setup.diagnostics)
        rec.update(
            method_used=fr.method,
            maps=[{"role": m.role, "size": [int(v) for v in m.size]} for m in setup.maps],
            texels=texels, diagnostics=diagnostics(setup),
            fallbacks=[list(x) for x in fallbacks], notes=[list(x) for x in notes],
            warnings=fr.warnings,
            errors=errs.to_json(),
            footprint_lit=analysis.footprint_summary(fp_img, lit),
            footprint_all=footprint_stats(fp).to_json(),
            anatomy=analysis.anatomy(fr.shadow, gt.shadow, comp, out["_images"]["facing"], fr.map_index, fp_img,
                                     opts.band_radius).to_json(),
            excluded_pixels=int((gt.valid & ~comp).sum()),
            shading_vs_truth=shading_difference(fr.combined, fr.shadow, comp, run.out["_images"]["truth"],
                                                gt.shadow),
        )
        persp = footprint_stats(perspective_footprints(view, light, setup, gt.points[lit]))
        rec["perspective_footprint"] = persp.to_json()
        if out.get("n_min"):
            mm = lloyd.m_min(out["n_min"], texels)
            rec["m_min"] = mm
            rec["max_over_limit"] = persp.max / mm if mm > 0 else None
        if len(run.frames) > 1:
            rec["flicker"] = flicker(np.stack(states), np.stack([g.shadow for g in gts]), np.stack(valids)).to_json()
        rec["_images"] = {"render": fr.combined, "shadow": fr.shadow, "comparable": comp, "footprint": fp_img,
                          "maps": fr.shadow_maps[:6], "map_roles": [m.role for m in setup.maps][:6]}
        rec["_settings"] = settings
    except Exception as exc:  # noqa: BLE001 - a failed method is reported, never fatal
        rec.clear()
        rec.update(method=method, size=size, status="failed", reason=f"{type(exc).__name__}: {exc}",
                   trace=traceback.format_exc(limit=3))
    return rec


def _say_method(progress: Progress, label: str, rec: dict) -> None:
    if rec["status"] != "ok":
        progress.log(f"{label}: {rec['method']} @ {rec['size']} FAILED: {rec['reason']}")
        return
    e, fp = rec["errors"], rec["footprint_lit"]
    fb = f"; FALLBACK: {rec['fallbacks'][0][1]}" if rec["fallbacks"] else ""
    fb += "".join(f"; note ({what}): {why.split(':')[0]}" for what, why in rec.get("notes", []))
    progress.log(f"{label}: {rec['method']} @ {rec['size']}: {100 * e['error_rate']:.2f} % wrong "
                 f"({e['false_light']} false light, {e['false_shadow']} false shadow), footprint p95 "
                 f"{fp['p95']:.2f} px, {len(rec['maps'])} map(s){fb}")


def _time_methods(run: SceneRun) -> None:
    """The timing rounds: each round renders frame 0 once with every method and
    size (interleaved, so load bursts fall on all points alike)."""
    import bpy
    from .lixel import timed_frame
    from .timing import load_average, summarise
    recs = [r for r in run.out["methods"] if r["status"] == "ok"]
    runs = {id(r): [] for r in recs}
    run.scene.frame_set(run.frames[0])
    loads = [load_average()]
    for r_i in range(run.opts.repeats):
        with run.progress.step("timing", f"{run.name}: timing round {r_i + 1}/{run.opts.repeats} "
                                         f"({len(recs)} points)", run.name):
            for rec in recs:
                runs[id(rec)].append(timed_frame(bpy.context.evaluated_depsgraph_get(), rec["_settings"],
                                                 run.opts.resolution))
        loads.append(load_average())
    load = float(np.nanmean(loads))
    for rec in recs:
        if runs[id(rec)]:
            rec["timing"] = summarise(runs[id(rec)], rec.pop("_stages", []), rec.pop("_first_s", math.nan),
                                      load).to_json()
    if recs:
        fastest = min(recs, key=lambda r: r["timing"]["median_ms"])
        slowest = max(recs, key=lambda r: r["timing"]["median_ms"])
        run.progress.log(f"{run.name}: Lixel frames {fastest['timing']['median_ms']:.0f} ms ({fastest['method']} "
                         f"@ {fastest['size']}) to {slowest['timing']['median_ms']:.0f} ms ({slowest['method']} "
                         f"@ {slowest['size']}) CPU time, medians of {run.opts.repeats} (load average {load:.1f})")


def _explain(out: dict) -> None:
    """Per record, where the analytic footprint and the rendered error disagree:
    against uniform at the same size, and against the method's next smaller size."""
    from .analysis import explain
    ok = {(r["method"], r["size"]): r for r in out["methods"] if r["status"] == "ok"}
    sizes = sorted({s for _, s in ok})
    for (method, size), rec in ok.items():
        notes = []
        ref = ok.get(("uniform", size))
        if method != "uniform" and ref is not None:
            text = explain(rec, ref, "uniform")
            if text:
                notes.append(text)
        smaller = [s for s in sizes if s < size and (method, s) in ok]
        if smaller:
            text = explain(rec, ok[(method, smaller[-1])], f"{smaller[-1]}²")
            if text:
                notes.append(text)
        rec["explanation"] = notes


def _peer(run: SceneRun, peer: str) -> None:
    import bpy
    from addon.gpu.pipeline import DEFAULT_ALBEDO
    from addon.measure import classify
    from addon.scene.describe import pick_light
    from . import analysis
    from .peers import PeerSession

    opts, out, gt = run.opts, run.out, run.gts[0]
    samples = opts.eevee_samples if peer == "eevee" else opts.cycles_samples
    sizes = opts.eevee_at() if peer == "eevee" else [None]
    facing = out["_images"]["facing"]
    light_obj = pick_light(run.scene, bpy.context.evaluated_depsgraph_get())
    try:
        with PeerSession(run.scene, light_obj, peer, samples, DEFAULT_ALBEDO) as session:
            with run.progress.step(f"{peer} reference", f"{run.name}: {peer} reference renders "
                                                       f"(no shadows, then the first with shadows)", run.name):
                with quiet_blender():
                    session.reference()
            for size in sizes:
                rec = {"method": peer, "status": "ok", "samples": samples}
                if size:
                    rec["size"] = int(size)
                out["peers"].append(rec)
                with run.progress.step(peer, f"{run.name}: {peer}" + (f" @ {size}" if size else "") +
                                       f", {opts.peer_repeats} timed render(s)", run.name):
                    try:
                        with quiet_blender():
                            res = session.shadowed(opts.peer_repeats, size)
                    except Exception as exc:  # noqa: BLE001
                        rec.update(status="failed", reason=f"{type(exc).__name__}: {exc}")
                        run.progress.log(f"{run.name}: {peer} FAILED: {exc}")
                        continue
                comp = gt.valid & res.lit
                errs = classify(res.shadow, gt.shadow, comp, opts.band_radius)
                rec.update(settings=res.settings, timing=res.timing.to_json(), errors=errs.to_json(),
                           shading_vs_truth=shading_difference(res.image, res.shadow, comp, out["_images"]["truth"],
                                                               gt.shadow),
                           anatomy=analysis.anatomy(res.shadow, gt.shadow, comp, facing, np.zeros(gt.shape, int),
                                                    np.full(gt.shape, np.nan), opts.band_radius).to_json(),
                           excluded_pixels=int((gt.valid & ~comp).sum()),
                           _images={"render": res.image, "shadow": res.shadow, "comparable": comp})
                run.progress.log(f"{run.name}: {peer}" + (f" @ {size}" if size else "") +
                                 f": {100 * errs.error_rate:.2f} % wrong, {res.timing.median_ms / 1000:.2f} s CPU time "
                                 f"a render ({res.timing.wall_median_ms / 1000:.2f} s wall; medians of "
                                 f"{res.timing.repeats})")
    except Exception as exc:  # noqa: BLE001
        out["peers"].append({"method": peer, "status": "failed", "reason": f"{type(exc).__name__}: {exc}"})
        run.progress.log(f"{run.name}: {peer} FAILED: {exc}")
        run.progress.drop(run.name, peer)


def _overlays(run: SceneRun) -> None:
    from . import overlays
    try:
        with quiet_blender():
            run.out["overlays"] = overlays.snapshots(run.scene, run.opts)
    except Exception as exc:  # noqa: BLE001 - reported in the document
        run.out["overlays_error"] = f"{type(exc).__name__}: {exc}"
        run.progress.log(f"{run.name}: overlay snapshots FAILED: {exc}")


def run(opts: Options, progress: Progress) -> dict:
    """Run every scene (a scene that fails is recorded, never fatal)."""
    import bpy
    workdir = Path(tempfile.mkdtemp(prefix="lixel-report-"))
    result = {"options": {"scenes": list(map(str, opts.scenes)), "methods": list(opts.methods),
                          "sizes": [int(s) for s in opts.sizes], "resolution": list(opts.resolution),
                          "frames": opts.frames, "peers": list(opts.peers), "quick": opts.quick,
                          "eevee_samples": opts.eevee_samples, "cycles_samples": opts.cycles_samples,
                          "eevee_sizes": [int(s) for s in opts.eevee_at()] if "eevee" in opts.peers else [],
                          "repeats": opts.repeats, "peer_repeats": opts.peer_repeats,
                          "band_radius": opts.band_radius},
              "blender": bpy.app.version_string, "scenes": [], "_workdir": workdir}
    for name in opts.scenes:
        try:
            result["scenes"].append(run_scene(str(name), opts, progress, workdir))
        except Exception as exc:  # noqa: BLE001
            label = Path(str(name)).stem
            progress.log(f"scene {label} FAILED: {type(exc).__name__}: {exc}")
            progress.drop(label)
            result["scenes"].append({"name": label, "status": "failed", "reason": f"{type(exc).__name__}: {exc}",
                                     "trace": traceback.format_exc(limit=4), "methods": [], "peers": []})
    result["seconds"] = progress.elapsed()
    return result


def cleanup(result: dict) -> None:
    shutil.rmtree(result.get("_workdir", ""), ignore_errors=True)
