"""The report's pictures (matplotlib, Agg; no pyplot state). Images are (H, W)
with row 0 at the bottom, drawn with ``origin='lower'``."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from addon.measure.errors import error_image

PANEL_W = 3.0   # inches per panel


def _figure(rows: int, cols: int, aspect: float):
    fig = Figure(figsize=(PANEL_W * cols, PANEL_W * aspect * rows + 0.45 * rows + 0.3), dpi=90,
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


def _lookup(scene, method, size):
    for m in scene["methods"]:
        if m["method"] == method and m["size"] == size:
            return m
    return None


def _failed(ax, rec):
    reason = (rec or {}).get("reason", "not run")
    ax.text(0.5, 0.5, "FAILED\n" + "\n".join(reason[i:i + 32] for i in range(0, min(len(reason), 128), 32)),
            ha="center", va="center", fontsize=7, color="darkred", transform=ax.transAxes, wrap=True)


def renders(scene: dict, path: Path) -> Path:
    """Ground truth and the peers on the first row; methods (columns) by map size (rows)."""
    sizes, names = _grid(scene)
    img = scene["_images"]
    h, w = img["hit"].shape
    cols = max(len(names), 1 + len(scene["peers"]))
    fig, axes = _figure(1 + len(sizes), cols, h / w)
    axes[0, 0].imshow(img["truth"], origin="lower", cmap="gray", vmin=0, vmax=1)
    axes[0, 0].set_title("ground truth (ray cast)", fontsize=9)
    for j, p in enumerate(scene["peers"], start=1):
        ax = axes[0, j]
        if p.get("status") == "ok":
            ax.imshow(np.clip(p["_images"]["render"], 0, 1), origin="lower", cmap="gray", vmin=0, vmax=1)
            ax.set_title(f"{p['method']} ({p['total_ms'] / 1000:.1f} s)", fontsize=9)
        else:
            ax.set_title(p["method"], fontsize=9)
            _failed(ax, p)
    for j in range(1 + len(scene["peers"]), cols):
        axes[0, j].axis("off")
    for i, size in enumerate(sizes, start=1):
        for j, name in enumerate(names):
            ax = axes[i, j]
            rec = _lookup(scene, name, size)
            ax.set_title(f"{name} {size}²", fontsize=9)
            if rec and rec.get("status") == "ok":
                ax.imshow(np.clip(rec["_images"]["render"], 0, 1), origin="lower", cmap="gray", vmin=0, vmax=1)
            else:
                _failed(ax, rec)
        for j in range(len(names), cols):
            axes[i, j].axis("off")
    return _save(fig, path)


def errors(scene: dict, path: Path) -> Path:
    """Error images: red = false shadow, blue = false light (grey: correct)."""
    sizes, names = _grid(scene)
    img = scene["_images"]
    h, w = img["hit"].shape
    cols = max(len(names), len(scene["peers"]))
    fig, axes = _figure(len(sizes) + 1, cols, h / w)
    truth = img["truth_shadow"]
    for j, p in enumerate(scene["peers"]):
        ax = axes[0, j]
        ax.set_title(p["method"], fontsize=9)
        if p.get("status") == "ok":
            ax.imshow(error_image(p["_images"]["shadow"], truth, p["_images"]["comparable"]), origin="lower")
            ax.set_title(f"{p['method']}: {100 * p['errors']['error_rate']:.2f}%", fontsize=9)
        else:
            _failed(ax, p)
    for j in range(len(scene["peers"]), cols):
        axes[0, j].axis("off")
    for i, size in enumerate(sizes, start=1):
        for j, name in enumerate(names):
            ax = axes[i, j]
            rec = _lookup(scene, name, size)
            if rec and rec.get("status") == "ok":
                ax.imshow(error_image(rec["_images"]["shadow"], truth, rec["_images"]["comparable"]), origin="lower")
                ax.set_title(f"{name} {size}²: {100 * rec['errors']['error_rate']:.2f}%", fontsize=9)
            else:
                ax.set_title(f"{name} {size}²", fontsize=9)
                _failed(ax, rec)
        for j in range(len(names), cols):
            axes[i, j].axis("off")
    return _save(fig, path)


def footprints(scene: dict, path: Path) -> Path:
    """log2 of the texel footprint (screen pixels per texel): blue < 1 (sharp), red > 1 (blocky)."""
    sizes, names = _grid(scene)
    h, w = scene["_images"]["hit"].shape
    fig, axes = _figure(len(sizes), max(len(names), 1), h / w)
    last = None
    for i, size in enumerate(sizes):
        for j, name in enumerate(names):
            ax = axes[i, j]
            rec = _lookup(scene, name, size)
            ax.set_title(f"{name} {size}²", fontsize=9)
            if rec and rec.get("status") == "ok":
                fp = rec["_images"]["footprint"]
                with np.errstate(divide="ignore", invalid="ignore"):
                    lg = np.log2(fp)
                last = ax.imshow(np.ma.masked_invalid(lg), origin="lower", cmap="RdBu_r", vmin=-4, vmax=4)
                ax.set_facecolor("black")
                f = rec["footprint"]
                ax.set_title(f"{name} {size}²\nmax {f['max']:.1f}, p95 {f['p95']:.2f}", fontsize=8)
            else:
                _failed(ax, rec)
    if last is not None:
        cb = fig.colorbar(last, ax=axes.ravel().tolist(), shrink=0.8, pad=0.01)
        cb.set_label("log2 pixels per texel")
    fig.savefig(path)
    return path


def shadow_maps(scene: dict, path: Path) -> Path:
    """The depth maps of each method (columns) at the largest size, one row per map (up to 4)."""
    sizes, names = _grid(scene)
    size = max(sizes) if sizes else 0
    recs = [(n, _lookup(scene, n, size)) for n in names]
    rows = max([len(r["_images"]["maps"]) for _, r in recs if r and r.get("status") == "ok"] + [1])
    fig, axes = _figure(rows, max(len(recs), 1), 1.0)
    for j, (name, rec) in enumerate(recs):
        if not (rec and rec.get("status") == "ok"):
            axes[0, j].set_title(f"{name} {size}²", fontsize=9)
            _failed(axes[0, j], rec)
            for i in range(1, rows):
                axes[i, j].axis("off")
            continue
        maps = rec["_images"]["maps"]
        for i in range(rows):
            ax = axes[i, j]
            if i < len(maps):
                d = np.asarray(maps[i], dtype=np.float64)
                step = max(1, max(d.shape) // 512)
                d = d[::step, ::step]
                finite = d[(d > 0) & (d < 1)]
                lo, hi = (np.percentile(finite, [1, 99]) if finite.size else (0.0, 1.0))
                ax.imshow(d, origin="lower", cmap="gray", vmin=lo, vmax=max(hi, lo + 1e-6))
                ax.set_title(f"{name} {size}²: {rec['_images']['map_roles'][i]}", fontsize=9)
            else:
                ax.axis("off")
    return _save(fig, path)


def pareto_front(points):
    """Indices of the points (time, error) no other point beats in both."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], math.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def speed_error(scene: dict, path: Path) -> Path:
    """Error rate against time per frame; the Pareto front is joined and ringed."""
    fig = Figure(figsize=(7.5, 4.8), dpi=90, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    pts, labels, kinds = [], [], []
    for m in _ok(scene["methods"]):
        pts.append((m["total_ms"], 100 * m["errors"]["error_rate"]))
        labels.append(f"{m['method']} {m['size']}")
        kinds.append(m["method"])
    for p in _ok(scene["peers"]):
        pts.append((p["total_ms"], 100 * p["errors"]["error_rate"]))
        labels.append(p["method"])
        kinds.append(p["method"])
    names = list(dict.fromkeys(kinds))
    cmap = [f"C{i % 10}" for i in range(len(names))]
    for (x, y), lab, k in zip(pts, labels, kinds):
        ax.scatter([x], [max(y, 1e-3)], color=cmap[names.index(k)], s=30, zorder=3,
                   marker="s" if k in ("eevee", "cycles") else "o")
        ax.annotate(lab, (x, max(y, 1e-3)), fontsize=7, xytext=(3, 3), textcoords="offset points")
    if pts:
        front = pareto_front(pts)
        fx = [pts[i][0] for i in front]
        fy = [max(pts[i][1], 1e-3) for i in front]
        ax.plot(fx, fy, "k--", lw=1, zorder=2, label="Pareto front")
        ax.scatter(fx, fy, s=140, facecolors="none", edgecolors="k", zorder=4)
        ax.set_xscale("log")
        ax.set_yscale("log")
        for k, c in zip(names, cmap):
            ax.scatter([], [], color=c, label=k)
        ax.legend(fontsize=7, loc="best")
    else:
        ax.text(0.5, 0.5, "no successful method", ha="center", transform=ax.transAxes)
    ax.set_xlabel("time per frame [ms] (Lixel: CPU setup + depth pass + shading; peers: one render)")
    ax.set_ylabel("misclassified pixels [%]")
    ax.set_title(f"{scene['name']}: speed against error")
    ax.grid(True, which="both", alpha=0.3)
    return _save(fig, path)


def comparison(scene: dict, methods: list, size: int, path: Path) -> Path:
    """A compact picture for the README: ground truth, the given methods at one
    size and the peers, each over its error image."""
    img = scene["_images"]
    h, w = img["hit"].shape
    recs = [r for r in (_lookup(scene, m, size) for m in methods) if r and r.get("status") == "ok"]
    peers = _ok(scene["peers"])
    cols = 1 + len(recs) + len(peers)
    fig, axes = _figure(2, cols, h / w)
    axes[0, 0].imshow(img["truth"], origin="lower", cmap="gray", vmin=0, vmax=1)
    axes[0, 0].set_title("ground truth", fontsize=9)
    axes[1, 0].imshow(error_image(img["truth_shadow"], img["truth_shadow"], img["valid"]), origin="lower")
    axes[1, 0].set_title("true shadows", fontsize=9)
    for j, r in enumerate(recs + peers, start=1):
        label = f"{r['method']} {size}²" if "size" in r else r["method"]
        axes[0, j].imshow(np.clip(r["_images"]["render"], 0, 1), origin="lower", cmap="gray", vmin=0, vmax=1)
        axes[0, j].set_title(f"{label}, {r['total_ms']:.0f} ms", fontsize=9)
        axes[1, j].imshow(error_image(r["_images"]["shadow"], img["truth_shadow"], r["_images"]["comparable"]),
                          origin="lower")
        axes[1, j].set_title(f"{100 * r['errors']['error_rate']:.2f}% wrong", fontsize=9)
    return _save(fig, path)
