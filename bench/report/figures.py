"""The report's pictures (matplotlib, Agg; no pyplot state). Images are (H, W)
with row 0 at the bottom, drawn with ``origin='lower'``.

Every figure carries its key: the renders a radiance bar (one exposure per
scene for every renderer, sRGB display), the error images the meaning of
their colours, the footprints and shadow maps colour bars with units, the
speed plot a legend of methods (colour) and map sizes (marker), with no text
placed on the data. Overlay snapshots get the viewport's colours as a legend.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib import colors as mcolors
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from addon.measure.errors import ERROR_COLOURS, error_image

PANEL_W = 3.0   # inches per panel
DPI = 100
PEER_NAMES = ("eevee", "cycles")
SIZE_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")

NOT_COUNTED = (246, 236, 206)
"""The error images' colour for pixels no count includes: cream, so that it is not taken for the light grey of
correct lit pixels (``addon.measure.errors`` draws them white)."""
ERROR_KEY = [
    ("false shadow: dark where the truth is lit", ERROR_COLOURS["false_shadow"]),
    ("false light: lit where the truth is dark", ERROR_COLOURS["false_light"]),
    ("correct, lit", ERROR_COLOURS["lit"]),
    ("correct, in shadow", ERROR_COLOURS["shadow"]),
    ("not counted (sky, turned from the light, silhouettes: see 'Counted pixels')", NOT_COUNTED),
]


def error_rgb(shadow, truth, counted) -> np.ndarray:
    """``addon.measure.errors.error_image`` with the pixels not counted in :data:`NOT_COUNTED`."""
    img = error_image(shadow, truth, counted)
    img[~np.asarray(counted, dtype=bool)] = NOT_COUNTED
    return img


def _figure(rows: int, cols: int, aspect: float, extra_h: float = 0.0):
    fig = Figure(figsize=(PANEL_W * cols, PANEL_W * aspect * rows + 0.5 * rows + 0.3 + extra_h), dpi=DPI,
                 layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, cols, squeeze=False)
    for ax in axes.ravel():
        ax.set_xticks([])
        ax.set_yticks([])
    return fig, axes


def _save(fig, path: Path) -> Path:
    fig.savefig(path)
    return path


def _ok(methods):
    return [m for m in methods if m.get("status") == "ok"]


def _grid(scene: dict):
    """(sizes, methods) for the method grids."""
    sizes = sorted({m["size"] for m in scene["methods"]})
    names = list(dict.fromkeys(m["method"] for m in scene["methods"]))
    return sizes, names


def _lookup(records, method, size):
    for m in records:
        if m["method"] == method and m.get("size") == size:
            return m
    return None


def _eevee_at(scene, size):
    return _lookup(scene["peers"], "eevee", size)


def _cycles(scene):
    return next((p for p in scene["peers"] if p["method"] == "cycles"), None)


def _failed(ax, rec):
    reason = (rec or {}).get("reason", "not run")
    ax.text(0.5, 0.5, "FAILED\n" + "\n".join(reason[i:i + 34] for i in range(0, min(len(reason), 136), 34)),
            ha="center", va="center", fontsize=7, color="darkred", transform=ax.transAxes)


def _blank(ax):
    ax.axis("off")


def _fell(rec) -> str:
    """Marks for a method that fell back (the reason is in the report's Diagnostics) or holds more
    texels than its size² budget."""
    mark = " ⚠fallback" if rec and rec.get("fallbacks") else ""
    if rec and rec.get("texels") and rec.get("size"):
        over = rec["texels"] / rec["size"] ** 2
        if over > 1.01:
            mark += f" ({over:.3g}× texels)"
    return mark


def _ms(rec) -> str:
    """The median CPU time of a timed record, as text."""
    t = rec.get("timing")
    if not t:
        return ""
    m = t["median_ms"]
    return (f"{m / 1000:.2f} s" if m >= 1000 else f"{m:.0f} ms") + " CPU"


def _method_grid(scene, axes, sizes, names, eevee_col: bool, draw, fontsize: int) -> None:
    """The panels after row 0's first (the truth's): Cycles beside it, then a row per map size of the methods and, in
    the last column, EEVEE where it ran at that size; unused panels blank. ``draw(ax, rec, label)`` shows a record that
    ran and returns its title; one that failed (or never ran) shows its label and why."""
    cy = _cycles(scene)
    panels = [(axes[0, 1], cy, "Cycles")] if cy is not None and axes.shape[1] > 1 else []
    for j in range(1 + len(panels), axes.shape[1]):
        _blank(axes[0, j])
    for i, size in enumerate(sizes, start=1):
        for j, name in enumerate(names):
            rec = _lookup(scene["methods"], name, size)
            panels.append((axes[i, j], rec, f"{name}{_fell(rec)} {size}²"))
        if eevee_col:
            ev = _eevee_at(scene, size)
            if ev is None:
                _blank(axes[i, len(names)])
            else:
                panels.append((axes[i, len(names)], ev, f"EEVEE {size}²"))
    for ax, rec, label in panels:
        if rec and rec.get("status") == "ok":
            ax.set_title(draw(ax, rec, label), fontsize=fontsize)
        else:
            ax.set_title(label, fontsize=fontsize)
            _failed(ax, rec)


# --------------------------------------------------------------------------- renders

def srgb(linear: np.ndarray) -> np.ndarray:
    """The sRGB transfer function of linear values clipped to [0, 1]."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def _display(radiance: np.ndarray, exposure: float) -> np.ndarray:
    img = np.asarray(radiance, dtype=np.float64)
    if img.ndim == 3:
        img = 0.2126 * img[..., 0] + 0.7152 * img[..., 1] + 0.0722 * img[..., 2]
    return srgb(img * exposure)


def _radiance_bar(fig, axes, exposure: float):
    """A colour bar in radiance units for images shown with :func:`_display`."""
    top = 1.0 / exposure
    grey = mcolors.ListedColormap(np.repeat(srgb(np.linspace(0, 1, 256))[:, None], 3, axis=1))
    sm = __import__("matplotlib.cm", fromlist=["ScalarMappable"]).ScalarMappable(
        norm=mcolors.Normalize(0, top), cmap=grey)
    cb = fig.colorbar(sm, ax=axes, shrink=0.7, pad=0.01, aspect=30)
    cb.set_label("radiance (scene-linear, Blender's units)\none exposure for every panel, sRGB display")
    return cb


def renders(scene: dict, path: Path) -> Path:
    """Ground truth and Cycles on the first row; per map size a row of the
    methods and, where EEVEE ran at that size, EEVEE. One exposure for all."""
    sizes, names = _grid(scene)
    img = scene["_images"]
    h, w = img["hit"].shape
    eevee_col = any(_eevee_at(scene, s) for s in sizes)
    cols = max(len(names) + int(eevee_col), 2)
    fig, axes = _figure(1 + len(sizes), cols, h / w)
    e = scene.get("exposure", 1.0)
    show = dict(origin="lower", cmap="gray", vmin=0, vmax=1, interpolation="nearest")
    axes[0, 0].imshow(_display(img["truth"], e), **show)
    axes[0, 0].set_title("ground truth (ray cast)", fontsize=9)

    def draw(ax, rec, label):
        ax.imshow(_display(rec["_images"]["render"], e), **show)
        return label + (f", {rec['samples']} spp" if rec["method"] == "cycles" else "") + f", {_ms(rec)}"
    _method_grid(scene, axes, sizes, names, eevee_col, draw, fontsize=9)
    _radiance_bar(fig, axes[:, -1].tolist(), e)
    return _save(fig, path)


# --------------------------------------------------------------------------- errors

def _error_key(fig, loc="outside lower center", ncol=3):
    handles = [Patch(facecolor=np.asarray(c) / 255, edgecolor="0.4", label=t) for t, c in ERROR_KEY]
    fig.legend(handles=handles, loc=loc, ncol=ncol, fontsize=8, frameon=False)


def _error_title(label: str, rec: dict) -> str:
    e = rec["errors"]
    return (f"{label}: {100 * e['error_rate']:.2f} % wrong\n"
            f"{e['false_shadow']} false shadow, {e['false_light']} false light")


def errors(scene: dict, path: Path) -> Path:
    """Error images: red = false shadow, blue = false light, greys correct (key below)."""
    sizes, names = _grid(scene)
    img = scene["_images"]
    h, w = img["hit"].shape
    truth = img["truth_shadow"]
    eevee_col = any(_eevee_at(scene, s) for s in sizes)
    cols = max(len(names) + int(eevee_col), 1)
    fig, axes = _figure(len(sizes) + 1, cols, h / w, extra_h=0.6)
    axes[0, 0].imshow(error_rgb(truth, truth, img["valid"]), origin="lower", interpolation="nearest")
    axes[0, 0].set_title("ground truth's shadows", fontsize=8)

    def draw(ax, rec, label):
        ax.imshow(error_rgb(rec["_images"]["shadow"], truth, rec["_images"]["comparable"]), origin="lower",
                  interpolation="nearest")
        return _error_title(label, rec)
    _method_grid(scene, axes, sizes, names, eevee_col, draw, fontsize=8)
    _error_key(fig, ncol=3 if cols > 2 else 2)
    return _save(fig, path)


# --------------------------------------------------------------------------- footprints

def footprints(scene: dict, path: Path) -> Path:
    """log2 of the analytic texel footprint (screen pixels per texel) on every
    counted pixel; pixels not lit-facing (left out of the statistics) are hatched grey."""
    sizes, names = _grid(scene)
    h, w = scene["_images"]["hit"].shape
    lit = scene["_images"].get("lit_facing")
    fig, axes = _figure(len(sizes), max(len(names), 1), h / w)
    last = None
    for i, size in enumerate(sizes):
        for j, name in enumerate(names):
            ax = axes[i, j]
            rec = _lookup(scene["methods"], name, size)
            ax.set_title(f"{name} {size}²", fontsize=9)
            if rec and rec.get("status") == "ok":
                fp = rec["_images"]["footprint"]
                with np.errstate(divide="ignore", invalid="ignore"):
                    lg = np.log2(fp)
                ax.set_facecolor("black")
                last = ax.imshow(np.ma.masked_invalid(lg), origin="lower", cmap="RdBu_r", vmin=-4, vmax=4,
                                 interpolation="nearest")
                if lit is not None:
                    grazing = np.isfinite(fp) & ~lit
                    ax.imshow(np.ma.masked_where(~grazing, np.ones_like(fp)), origin="lower",
                              cmap=mcolors.ListedColormap(["0.55"]), vmin=0, vmax=1, interpolation="nearest")
                f = rec["footprint_lit"]
                ax.set_title(f"{name}{_fell(rec)} {size}²\n"
                             f"p95 {f['p95']:.2f} px, {100 * f['frac_above_1']:.0f} % above 1",
                             fontsize=8)
            else:
                _failed(ax, rec)
    if last is not None:
        cb = fig.colorbar(last, ax=axes.ravel().tolist(), shrink=0.8, pad=0.01)
        ticks = np.arange(-4, 5, 2)
        cb.set_ticks(ticks)
        cb.set_ticklabels([f"1/{2 ** -t:g}" if t < 0 else f"{2 ** t:g}" for t in ticks])
        cb.set_label("screen pixels per texel (log scale)\nred: blocky, blue: finer than pixels;\n"
                     "grey: shadowed or n·l < 0.1, left out of p95")
    fig.savefig(path)
    return path


# --------------------------------------------------------------------------- shadow maps

def shadow_maps(scene: dict, path: Path, columns: int = 6) -> Path:
    """Every map of each method at the largest size (up to 6 a method), one
    panel each in reading order, each with its own depth bar; dark blue: no
    caster drawn there."""
    sizes, names = _grid(scene)
    ok_sizes = sorted({m["size"] for m in _ok(scene["methods"])})
    size = max(ok_sizes or sizes or [0])
    panels = []
    for name in names:
        rec = _lookup(scene["methods"], name, size)
        if rec and rec.get("status") == "ok":
            for depth, role in zip(rec["_images"]["maps"], rec["_images"]["map_roles"]):
                panels.append((f"{name}{_fell(rec)} {size}²: {role}", depth, None))
        else:
            panels.append((f"{name} {size}²", None, rec))
    cols = max(1, min(columns, len(panels)))
    rows = math.ceil(len(panels) / cols)
    fig, axes = _figure(rows, cols, 1.0)
    fig.set_size_inches(PANEL_W * 1.25 * cols, PANEL_W * rows + 0.8)
    empty = mcolors.ListedColormap([(0.05, 0.05, 0.15)])
    for ax, (title, depth, rec) in zip(axes.ravel(), panels):
        ax.set_title(title, fontsize=9)
        if depth is None:
            _failed(ax, rec)
            continue
        d = np.asarray(depth, dtype=np.float64)
        step = max(1, max(d.shape) // 512)
        d = d[::step, ::step]
        written = (d > 0) & (d < 1)
        lo, hi = (np.percentile(d[written], [1, 99]) if written.any() else (0.0, 1.0))
        ax.imshow(np.ma.masked_where(written, np.zeros_like(d)), origin="lower", cmap=empty, interpolation="nearest")
        im = ax.imshow(np.ma.masked_where(~written, d), origin="lower", cmap="gray_r", vmin=lo,
                       vmax=max(hi, lo + 1e-6), interpolation="nearest")
        cb = fig.colorbar(im, ax=ax, shrink=0.85, pad=0.02)
        cb.ax.tick_params(labelsize=6)
        cb.set_label("window depth (0 = near the light)", fontsize=6)
    for ax in axes.ravel()[len(panels):]:
        _blank(ax)
    fig.supxlabel("bright = near the light; dark blue = no caster drawn there (the map's clear value); each panel's "
                  "grey scale spans its own 1st to 99th percentile of depth", fontsize=8)
    return _save(fig, path)


# --------------------------------------------------------------------------- speed against error

def pareto_front(points):
    """Indices of the points (time, error) no other point beats in both."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], math.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def speed_points(scene: dict) -> list:
    """(median ms, min ms, max ms, error %, method, size or None) of every timed point."""
    out = []
    for r in _ok(scene["methods"]) + _ok(scene["peers"]):
        t = r.get("timing")
        if t:
            out.append((t["median_ms"], t["min_ms"], t["max_ms"], 100 * r["errors"]["error_rate"], r["method"],
                        r.get("size")))
    return out


def speed_error(scene: dict, path: Path) -> Path:
    """Error against time per frame (median, bars from min to max); colour =
    method, marker = map size; the Pareto front joined and ringed."""
    fig = Figure(figsize=(9.0, 5.2), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    pts = speed_points(scene)
    if not pts:
        ax.text(0.5, 0.5, "no successful method", ha="center", transform=ax.transAxes)
        return _save(fig, path)
    floor = min([p[3] for p in pts if p[3] > 0] + [1.0]) / 3
    names = list(dict.fromkeys(p[4] for p in pts))
    sizes = sorted({p[5] for p in pts if p[5] is not None})
    colour = {n: f"C{i % 10}" for i, n in enumerate(names)}
    marker = {s: SIZE_MARKERS[i % len(SIZE_MARKERS)] for i, s in enumerate(sizes)}
    for med, lo, hi, err, name, size in pts:
        y = max(err, floor)
        ax.errorbar([med], [y], xerr=[[med - lo], [hi - med]], fmt=marker.get(size, "*"), color=colour[name],
                    ms=7 if size is not None else 11, capsize=2, lw=1, zorder=3,
                    mfc=colour[name] if err > 0 else "white")
    front = pareto_front([(p[0], p[3]) for p in pts])
    ax.plot([pts[i][0] for i in front], [max(pts[i][3], floor) for i in front], "k--", lw=1, zorder=2)
    ax.scatter([pts[i][0] for i in front], [max(pts[i][3], floor) for i in front], s=220, facecolors="none",
               edgecolors="k", zorder=4)
    ax.set_xscale("log")
    ax.set_yscale("log")
    over = {r["method"] for r in _ok(scene["methods"]) if _fell(r).endswith("texels)")}
    handles = [Line2D([], [], color=colour[n], marker="o", ls="",
                      label=n + (" (more texels than size²)" if n in over else "")) for n in names]
    handles += [Line2D([], [], color="0.3", marker=marker[s], ls="", label=f"{s}² map") for s in sizes]
    if any(p[5] is None for p in pts):
        handles.append(Line2D([], [], color="0.3", marker="*", ms=11, ls="", label="no map size (Cycles)"))
    handles.append(Line2D([], [], color="k", ls="--", marker="o", mfc="none", ms=12, label="Pareto front"))
    if any(p[3] == 0 for p in pts):
        handles.append(Line2D([], [], color="0.3", marker="o", mfc="white", ls="", label="0 % (drawn at the floor)"))
    fig.legend(handles=handles, fontsize=8, loc="outside right upper")
    ax.set_xlabel("CPU time per frame [ms] (the whole process, every thread), median; bar: min to max\n"
                  "(Lixel: the render engine's whole frame; peers: one render, no file written)")
    ax.set_ylabel("misclassified pixels [%]")
    ax.set_title(f"{scene['name']}: speed against error")
    ax.grid(True, which="both", alpha=0.3)
    return _save(fig, path)


# --------------------------------------------------------------------------- README comparison

def comparison(scene: dict, methods: list, size: int, path: Path) -> Path:
    """The README picture: error images of the given methods and EEVEE at one
    map size, two per row so each is large enough to see single wrong pixels,
    each titled with its error and median frame time; the colour key below."""
    img = scene["_images"]
    h, w = img["hit"].shape
    recs = [(f"Lixel {r['method']}", r) for r in (_lookup(scene["methods"], m, size) for m in methods)
            if r and r.get("status") == "ok"]
    ev = _eevee_at(scene, size) or next((p for p in _ok(scene["peers"]) if p["method"] == "eevee"), None)
    if ev is not None and ev.get("status") == "ok":
        recs.append((f"EEVEE", ev))
    cols = 2
    rows = math.ceil(len(recs) / cols)
    fig = Figure(figsize=(10.0, 10.0 / cols * h / w * rows + 0.9 * rows + 0.9), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    axes = np.atleast_2d(fig.subplots(rows, cols, squeeze=False))
    for ax in axes.ravel():
        ax.set_xticks([])
        ax.set_yticks([])
    truth = img["truth_shadow"]
    for k, (label, r) in enumerate(recs):
        ax = axes.ravel()[k]
        ax.imshow(error_rgb(r["_images"]["shadow"], truth, r["_images"]["comparable"]), origin="lower",
                  interpolation="nearest")
        e = r["errors"]
        sz = f" {r['size']}²" if r.get("size") else ""
        ax.set_title(f"{label}{sz}: {100 * e['error_rate']:.2f} % wrong, {_ms(r)} time a frame\n"
                     f"{e['false_shadow']} false shadow (red), {e['false_light']} false light (blue)", fontsize=10)
    for ax in axes.ravel()[len(recs):]:
        _blank(ax)
    _error_key(fig, ncol=2)
    return _save(fig, path)


# --------------------------------------------------------------------------- overlay snapshots

def _heat_cmap():
    from addon.ui.overlays import HEATMAP_COLOURS
    return mcolors.LinearSegmentedColormap.from_list("lixel_overlay_heat", list(HEATMAP_COLOURS))


def _heat_bar(fig, axes):
    from addon.ui.overlays import HEATMAP_LOG2_RANGE
    import matplotlib.cm as cm
    r = HEATMAP_LOG2_RANGE
    sm = cm.ScalarMappable(norm=mcolors.Normalize(-r, r), cmap=_heat_cmap())
    cb = fig.colorbar(sm, ax=axes, shrink=0.8, pad=0.01)
    ticks = np.arange(-r, r + 0.5, 1.0)
    cb.set_ticks(ticks)
    cb.set_ticklabels([f"1/{2 ** -t:g}" if t < 0 else f"{2 ** t:g}" for t in ticks])
    cb.set_label("screen pixels per texel (log scale, clamped)\nred: blocky; blue: texels finer than pixels")
    return cb


def _texel_key(fig, maps: int):
    from addon.ui.overlays import TEXEL_COLOURS
    handles = [Patch(facecolor=TEXEL_COLOURS["even map"], edgecolor="0.3", label="one texel: light square"),
               Patch(facecolor=TEXEL_COLOURS["dark"], edgecolor="0.3", label="its neighbour: dark square")]
    if maps > 1:
        handles.append(Patch(facecolor=TEXEL_COLOURS["odd map"], edgecolor="0.3",
                             label="light squares of maps 2, 4, 6 (cream)"))
    handles.append(Patch(facecolor=TEXEL_COLOURS["no map"], edgecolor="0.3", label="no map serves this surface"))
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=8, frameon=False)


def _line_key(fig, shot):
    from addon.ui.overlays import COLOURS
    handles = []
    if "frusta" in shot.flags:
        handles += [Line2D([], [], color=COLOURS["view"][:3], lw=2, label="camera's view frustum"),
                    Line2D([], [], color=COLOURS["light"][:3], lw=2, label="light frusta (each map's clip volume)")]
    if "body" in shot.flags:
        handles += [Patch(facecolor=(*COLOURS["body_face"], 0.35), edgecolor=COLOURS["body_edge"][:3],
                          label="intersection body B (Scherzer §4.1)")]
    if "warp" in shot.flags:
        handles += [Line2D([], [], color=COLOURS["warp"][:3], lw=2,
                           label="warp frustum P (drawn over its light frustum)"),
                    Line2D([], [], color=COLOURS["v_p"][:3], lw=2, label="V_P"),
                    Line2D([], [], color=COLOURS["middle_vector"][:3], lw=2, label="B's middle vector"),
                    Line2D([], [], color="white", marker="s", mec="0.3", ls="",
                           label="P's projection centre, B's centroid")]
    return handles


def overlay(shot, path: Path, scene_name: str) -> Path:
    """One overlay snapshot with its key: the texel checker's squares, the
    heatmap's colour bar, the observer's line colours."""
    n = len(shot.panels)
    h, w = shot.panels[0][1].shape[:2]
    width = 6.4 * n if shot.kind != "observer" else 10.5
    fig = Figure(figsize=(width, width / n * h / w + 1.4), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, n, squeeze=False)[0]
    for ax, (title, img) in zip(axes, shot.panels):
        ax.imshow(np.clip(img[..., :3], 0, 1), origin="lower", interpolation="nearest")
        ax.set_title(title, fontsize=10)
        ax.set_xticks([])
        ax.set_yticks([])
    what = {"texels": f"texel grid from the camera: each checker square is one texel of a {shot.size}² map",
            "heatmap": "texel footprint from the camera (the viewport's heatmap overlay)",
            "observer": "the whole setup seen from outside (the viewport's overlays)"}[shot.kind]
    fig.suptitle(f"{scene_name}: {what}", fontsize=11)
    if shot.kind == "texels":
        _texel_key(fig, shot.maps)
    else:
        _heat_bar(fig, axes.tolist())
    if shot.kind == "observer":
        handles = _line_key(fig, shot)
        fig.legend(handles=handles, loc="outside lower center", ncol=3, fontsize=8, frameon=False)
        if shot.notes:  # under the picture, above the key (a figure-level label would share the key's place)
            axes[0].set_xlabel("; ".join(shot.notes), fontsize=8, color="0.25")
    return _save(fig, path)
