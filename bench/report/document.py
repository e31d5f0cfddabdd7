"""Write the report: ``report.html`` and its Markdown twin ``report.md`` (both
built from one list of blocks), the figures under ``<scene>/`` and the
numbers in ``report.json``."""
from __future__ import annotations

import html
import json
import math
import urllib.parse
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import figures
from .analysis import NDL_MIN

README_METHODS = ("uniform", "lispsm", "plane_optimal")
"""Methods shown in the README picture (when run), with EEVEE."""

FIGURES = (("Renders", figures.renders, "renders.png"),
           ("Errors", figures.errors, "errors.png"),
           ("Footprint", figures.footprints, "footprint.png"),
           ("Shadow maps", figures.shadow_maps, "shadow_maps.png"),
           ("Speed against error", figures.speed_error, "speed_error.png"))
OVERLAY_FILES = {"texels": "overlay_texels.png", "heatmap": "overlay_heatmap.png", "observer": "overlay_observer.png"}
SECTIONS = ("Diagnostics", "Footprint against error", "Timing", "Renders", "Errors", "Footprint", "Shadow maps",
            "Speed against error", "Overlays", "Table")
"""The sections every scene gets, in order (the report test checks them)."""

DEFINITIONS = [
    ("Ground truth", "exact hard shadows per pixel: the first hit of the camera ray in a BVH of the scene's "
                     "triangles, then a ray from that point to the light."),
    ("Counted pixels", "a surface is visible, it faces the light and (spot) lies in the cone; Lixel pixels where "
                       "the rasterized surface differs from the ray-cast one (silhouettes), or shows the same point on "
                       "another face (a box's edge), are left out and counted as 'excluded'."),
    ("error %", "misclassified counted pixels; false shadow = dark where the truth is lit (red in the error "
                "images), false light = lit where the truth is dark (blue); 'at edges' = within 2 px of a true "
                "shadow edge."),
    ("flicker %", "over the camera animation, of the pixel transitions where the ground truth keeps its state, the "
                  "fraction where the method's state changes. The sample cameras move a surface point 3-35 pixels "
                  "a frame at 640×360, so this counts the method's error edges sliding across the pixels even where "
                  "its maps stand still in the world: python -m bench.cascade flicker splits it into that part and "
                  "the world-consistent flicker (the same surface point changing state as the maps change), with "
                  "the stable options on and off, and measures it on the same moves slowed to a few pixels a frame "
                  "or less (--speeds)."),
    ("footprint", "the analytic texel footprint of the method's matrices: screen pixels spanned by one texel in its "
                  "worst direction (largest singular value of the texel-to-pixel Jacobian on the surface); above 1 "
                  f"means blocky shadow edges. Its statistics (p95, share above 1) are over the lit-facing pixels "
                  f"(as in bench/rendered_error.py): counted, lit in the ground truth and turned to the light by "
                  f"n·l ≥ {NDL_MIN} (surfaces grazing the light have unbounded footprints whatever the warp). "
                  f"'edge p95': over the pixels turned to the light within 2 px of a true shadow edge, both sides."),
    ("m_min", "Lloyd's physical limit: the smallest maximum perspective footprint any parameterization can reach "
              "with the method's texel count N, sqrt(N_min / N). persp max/m_min: the method's largest perspective "
              "footprint over the lit-facing pixels, over that limit."),
    ("θ, γ, n_opt, λ", "θ: angle between the light and view directions folded to [0°, 90°] (GMNPR); γ: the same "
                       "in [0°, 180°] (LiSPSM); n_opt: the warp's near distance (LiSPSM, Scherzer Eq. 1); λ: the "
                       "GMNPR/GLPR parameter. Empty where a method has none."),
    ("Fallbacks", "what a method did instead of its own construction, with its reason (from the method's "
                  "diagnostics); a method that fell back is marked ⚠ wherever it appears."),
    ("Notes", "what a method adjusted within its own construction, e.g. the λ guard raising λ where the method's "
              "own λ would alias worse than the uniform map (docs/papers.md, 'The λ guard'); not marked ⚠."),
    ("times", "every timed point is the median of repeated runs, with min and max. What is timed — Lixel: the "
              "LIXEL render engine's whole F12 frame (addon.render.engine.render_depsgraph as the engine calls it): "
              "geometry from the cache, the scene described, the camera pre-pass, B and the warp, depth pass, "
              "shading, compose and the read-back of the engine's passes — from its start to the pixels in memory; "
              "geometry and GPU batches stay cached between frames, as in the engine; Python's garbage collector is "
              "held off during a timed frame; the first frame (shader compilation, uploads) is reported "
              "separately, and the stage times come from the measured frames, which wait for the GPU after each "
              "stage. The "
              "repeats of all Lixel points of a scene are interleaved. Peers: one bpy.ops.render.render from its "
              "call to the pixels in the Render Result, no file written, after one untimed render with shadows that "
              "compiles the shaders. How — the CPU time of the whole process over that span (every thread: Blender, "
              "llvmpipe's rasterizer threads, Cycles' render threads) is the timed point: this machine is shared, "
              "and the wall clock measures the other work on it as much as the frame (it is given beside, with the "
              "load average while it was measured). The stage times are the engine's own, wall clock."),
    ("peers", "EEVEE and Cycles with one grey diffuse material (Lixel's albedo), the scene's black world and its "
              "light only: the render with shadows divided by the one without, below 0.5 = shadow."),
    ("pictures", "every render is shown with one exposure per scene — the ground truth's unshadowed direct light at "
                 "its 99th percentile is white — and the sRGB transfer curve; the ground truth is shaded with "
                 "Lixel's own shading formula, the peers render the same grey material, so a difference in "
                 "brightness is a difference in light."),
]


# --------------------------------------------------------------------------- formatting

def _pct(x, digits=2):
    return "" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{100 * x:.{digits}f}"


def _num(x, fmt="{:.2f}"):
    if x is None:
        return ""
    if isinstance(x, float) and math.isnan(x):
        return ""
    if isinstance(x, float) and math.isinf(x):
        return "∞"
    return fmt.format(x)


def _label(r: dict) -> tuple[str, str]:
    """(method, map) cells of a record."""
    warn = " ⚠" if r.get("fallbacks") else ""
    if r["method"] in figures.PEER_NAMES:
        name = {"eevee": "EEVEE", "cycles": "Cycles"}[r["method"]]
        return name, (f"{r['size']}²" if r.get("size") else f"{r.get('samples', '')} spp")
    if not r.get("maps"):
        return r["method"] + warn, f"{r['size']}²"
    n, budget = len(r["maps"]), budget_factor(r)
    over = f", {budget:.3g}× the budget" if budget > BUDGET_TOLERANCE else ""
    return r["method"] + warn, f"{r['size']}²: {n} map{'s' if n > 1 else ''}, {r['texels'] / 1e6:.3g} M texels{over}"


BUDGET_TOLERANCE = 1.01
"""A method whose maps hold more than this times size² texels is flagged (it does not keep the texel budget)."""


def budget_factor(r: dict) -> float:
    """Texels of a record's maps over its size² budget."""
    return float(r.get("texels", 0.0)) / float(r["size"]) ** 2 if r.get("size") else 0.0


def _records(scene: dict) -> list:
    return scene["methods"] + scene["peers"]


# --------------------------------------------------------------------------- blocks

@dataclass
class Block:
    kind: str          # h1 h2 h3 p ul table img caption
    content: object
    extra: object = None


def _remarks(r: dict) -> str:
    """The diagnostics table's last cell: the method run instead, its fallbacks, its notes, the render's warnings."""
    ran = [f"ran as {r['method_used']}"] if r.get("method_used") and r["method_used"] != r["method"] else []
    return "; ".join(ran + [f"fallback {w}: {why}" for w, why in r.get("fallbacks", [])] +
                     [f"note {w}: {why}" for w, why in r.get("notes", [])] + list(r.get("warnings", [])))


def _tables(scene: dict) -> dict:
    diag_head = ["method", "map", "maps (roles)", "θ", "γ", "n_opt", "λ", "fallbacks, notes and warnings"]
    diag = []
    for r in scene["methods"]:
        m, size = _label(r)
        if r.get("status") != "ok":
            diag.append([m, size, "failed: " + r.get("reason", "")] + [""] * 5)
            continue
        d = r["diagnostics"]
        roles = ", ".join(x["role"] for x in r["maps"])
        diag.append([m, size, f"{len(r['maps'])} ({roles})", _num(d["theta_deg"], "{:.1f}°"),
                     _num(d["gamma_deg"], "{:.1f}°"), _num(d["n_opt"], "{:.4g}"), _num(d["lam"], "{:.4g}"),
                     _remarks(r)])
    fe_head = ["method", "map", "footprint p95 [px]", "edge p95 [px]", "fp > 1 %", "error %", "false light",
               "false shadow", "at edges %", "unserved %", "where footprint and error disagree"]
    fe = []
    for r in _records(scene):
        m, size = _label(r)
        if r.get("status") != "ok":
            fe.append([m, size] + [""] * 8 + ["failed: " + r.get("reason", "")])
            continue
        e, a, fp = r["errors"], r.get("anatomy", {}), r.get("footprint_lit", {})
        fe.append([m, size, _num(fp.get("p95")), _num(a.get("edge_footprint_p95")), _pct(fp.get("frac_above_1"), 0),
                   _pct(e["error_rate"]), str(e["false_light"]), str(e["false_shadow"]),
                   _pct(a.get("at_edges"), 0), _pct(a.get("unserved"), 0) if r["method"] not in figures.PEER_NAMES
                   else "", " ".join(r.get("explanation", []))])
    stage_names = list(dict.fromkeys(k for r in scene["methods"] if r.get("timing")
                                     for k in r["timing"]["stages_ms"]))
    t_head = (["method", "map", "CPU median ms", "CPU min", "CPU max", "wall median ms", "wall min", "wall max",
               "runs", "load", "first (wall) ms"] + [f"{k} (wall) ms" for k in stage_names])
    tm = []
    for r in _records(scene):
        m, size = _label(r)
        t = r.get("timing")
        if r.get("status") != "ok" or not t:
            continue
        tm.append([m, size] + [_num(t[k], "{:.1f}") for k in ("median_ms", "min_ms", "max_ms", "wall_median_ms",
                                                               "wall_min_ms", "wall_max_ms")]
                  + [str(t["repeats"]), _num(t.get("load"), "{:.1f}"), _num(t.get("first_ms"), "{:.0f}")]
                  + [_num(t["stages_ms"].get(k), "{:.1f}") for k in stage_names])
    big_head = ["method", "map", "error %", "false shadow", "false light", "edge error %", "flicker %",
                "fp max", "fp mean", "m_min", "persp max/m_min", "CPU median ms", "excluded"]
    big = []
    for r in _records(scene):
        m, size = _label(r)
        if r.get("status") != "ok":
            big.append([m, size, "failed: " + r.get("reason", "")] + [""] * (len(big_head) - 3))
            continue
        e, fp, fl = r["errors"], r.get("footprint_lit", {}), r.get("flicker")
        big.append([m, size, _pct(e["error_rate"]), str(e["false_shadow"]), str(e["false_light"]),
                    _pct(e["band_error_rate"]), _pct(fl["rate"]) if fl else "", _num(fp.get("max")),
                    _num(fp.get("mean")), _num(r.get("m_min"), "{:.3f}"), _num(r.get("max_over_limit"), "{:.1f}"),
                    _num(r["timing"]["median_ms"], "{:.1f}") if r.get("timing") else "",
                    str(r.get("excluded_pixels", ""))])
    return {"Diagnostics": (diag_head, diag), "Footprint against error": (fe_head, fe), "Timing": (t_head, tm),
            "Table": (big_head, big)}


def _facts(scene: dict) -> list[str]:
    v = scene.get("view", {})
    gt = scene.get("ground_truth", {})
    facts = [f"{scene.get('triangles', 0):,} triangles in {scene.get('instances', 0):,} instances",
             f"{scene['resolution'][0]}×{scene['resolution'][1]} pixels, frames "
             f"{scene['frames'][0]}–{scene['frames'][-1]}",
             f"{scene.get('light', '?')} light '{scene.get('light_name', '')}'; "
             f"camera '{scene.get('camera_name', '')}' "
             f"fov {v.get('fov_x_deg', 0):.1f}°×{v.get('fov_y_deg', 0):.1f}°, near {v.get('near', 0):g}, "
             f"far {v.get('far', 0):g}",
             f"ground truth: {gt.get('valid_pixels', 0):,} counted pixels ({scene.get('lit_facing_pixels', 0):,} "
             f"lit-facing), {100 * gt.get('shadow_fraction', 0):.1f} % in shadow, "
             f"{gt.get('seconds_per_frame', 0):.2f} s a frame"]
    if scene.get("n_min"):
        facts.append(f"Lloyd's N_min = {scene['n_min']:,.0f} texels (a {math.sqrt(scene['n_min']):,.0f}² map "
                     f"at footprint 1)")
    elif scene.get("n_min_reason"):
        facts.append(f"Lloyd's N_min: not defined here ({scene['n_min_reason']})")
    match = [(r["method"], r["shading_vs_truth"]) for r in _records(scene)
             if r.get("status") == "ok" and r.get("shading_vs_truth") is not None]
    if match:
        worst = max(match, key=lambda m: m[1])
        facts.append(f"same shading: on the pixels lit in both, every render's radiance is within "
                     f"{100 * worst[1]:.2g} % of the ground truth's (median; largest: {worst[0]})")
    for p in scene["peers"]:
        if p.get("settings"):
            facts.append(p["settings"] + (f" (at {p['size']}²)" if p.get("size") else ""))
    front = pareto_names(scene)
    if front:
        facts.append("Pareto front (fastest first): " + ", ".join(front))
    return facts


def _warnings(scene: dict) -> list[str]:
    out = []
    for r in scene["methods"]:
        for what, why in r.get("fallbacks", []):
            out.append(f"⚠ {r['method']} @ {r['size']}²: fell back ({what}): {why}; it made "
                       f"{len(r.get('maps', []))} map(s): {', '.join(m['role'] for m in r.get('maps', []))}")
    over = {}
    for r in scene["methods"]:
        if r.get("status") == "ok" and budget_factor(r) > BUDGET_TOLERANCE:
            over.setdefault(r["method"], []).append(f"{r['size']}²: {budget_factor(r):.3g}×")
    for method, where in over.items():
        out.append(f"⚠ {method} does not keep the texel budget: its maps hold more than size² texels "
                   f"({', '.join(where)}); compare it with the other methods at the size of equal texels")
    return out


def pareto_names(scene: dict) -> list[str]:
    pts = figures.speed_points(scene)
    return [f"{pts[i][4]}" + (f" {pts[i][5]}" if pts[i][5] else "")
            for i in figures.pareto_front([(p[0], p[3]) for p in pts])]


def summary_rows(result: dict) -> list[list[str]]:
    """One row per scene: for each map size the Lixel method with the fewest
    errors (its error % and median CPU time a frame), EEVEE at the largest size
    it ran, and Cycles."""
    sizes = sorted({m["size"] for s in result["scenes"] for m in s.get("methods", []) if m.get("status") == "ok"})
    rows = []
    for scene in result["scenes"]:
        if scene.get("status") != "ok":
            rows.append([scene["name"], "failed: " + scene.get("reason", "")] + [""] * (len(sizes) + 1))
            continue
        row = [scene["name"]]
        for size in sizes:
            cands = [m for m in scene["methods"] if m.get("status") == "ok" and m["size"] == size]
            if cands:
                b = min(cands, key=lambda m: m["errors"]["error_rate"])
                over = budget_factor(b)
                row.append(f"{b['method']}{' ⚠' if b.get('fallbacks') else ''} "
                           f"{100 * b['errors']['error_rate']:.2f} % ({figures._ms(b)})"
                           + (f" with {over:.3g}× the texels" if over > BUDGET_TOLERANCE else ""))
            else:
                row.append("")
        for peer in ("eevee", "cycles"):
            ps = [x for x in scene["peers"] if x["method"] == peer]
            p = max(ps, key=lambda x: x.get("size") or 0) if ps else None
            row.append("" if p is None else (f"{100 * p['errors']['error_rate']:.2f} % ({figures._ms(p)})"
                                             + (f" @ {p['size']}²" if p.get("size") else "")
                                             if p.get("status") == "ok" else "failed"))
        rows.append(row)
    return [["scene"] + [f"best at {s}²" for s in sizes] + ["EEVEE", "Cycles"]] + rows


def _header(result: dict) -> list[str]:
    o = result["options"]
    ev = f"EEVEE {o['eevee_samples']} spp at map size(s) {', '.join(map(str, o['eevee_sizes']))}" \
        if o.get("eevee_sizes") else "no EEVEE"
    shorter = [f"{s['name']} {len(s['frames'])}" for s in result.get("scenes", [])
               if 0 < len(s.get("frames", ())) < o["frames"]]   # (a scene's animation ends first: it said --frames)
    frames = f"{o['frames']} frame(s) of camera animation" + (f" (fewer where a scene's ends first: "
                                                              f"{', '.join(shorter)})" if shorter else "")
    return [f"Blender {result['blender']}; {'quick run' if o['quick'] else 'full run'}: scenes "
            f"{', '.join(o['scenes'])}; methods {', '.join(o['methods'])}; map sizes "
            f"{', '.join(str(s) for s in o['sizes'])}; {o['resolution'][0]}×{o['resolution'][1]} pixels; "
            f"{frames}; timing: median of {o['repeats']} frames per Lixel point, "
            f"{o['peer_repeats']} renders per peer point, in process CPU time (wall clock beside it); {ev}; Cycles "
            f"{o['cycles_samples']} spp (direct light only). Took {result.get('seconds', 0):.0f} s."]


def blocks(result: dict, pics: dict) -> list:
    out = [Block("h1", "Lixel: speed against error")]
    out += [Block("p", x) for x in _header(result)]
    out += [Block("h2", "How to read it"), Block("ul", [f"**{k}**: {v}" for k, v in DEFINITIONS])]
    summary = summary_rows(result)
    out += [Block("h2", "Summary"), Block("table", (summary[0], summary[1:]))]
    for scene in result["scenes"]:
        out.append(Block("h2", f"Scene: {scene['name']}", scene["name"]))
        if scene.get("status") != "ok":
            out.append(Block("p", f"**Failed**: {scene.get('reason', '')}"))
            continue
        out.append(Block("ul", _facts(scene)))
        warn = _warnings(scene)
        if warn:
            out.append(Block("ul", warn))
        tables = _tables(scene)
        made = pics.get(scene["name"], {})
        for section in SECTIONS:
            out.append(Block("h3", section))
            if section in tables:
                head, rows = tables[section]
                out.append(Block("table", (head, rows)))
            elif section == "Overlays":
                shots = made.get("Overlays") or []
                if not shots:
                    out.append(Block("p", f"(no overlay snapshots: {scene.get('overlays_error', 'not drawn')})"))
                for file, caption in shots:
                    out.append(Block("img", file, Path(file).stem.replace("_", " ")))
                    out.append(Block("caption", caption))
            else:
                pic = made.get(section)
                out.append(Block("img", pic, section) if pic else
                           Block("p", f"(figure failed: {scene.get('figure_errors', {}).get(section, '')})"))
    return out


def _md_inline(text: str) -> str:
    return text.replace("|", "/")


def _url(path: str) -> str:
    """A figure's relative path as a URL: a scene's folder is named after its .blend file, and a space in it ended a
    Markdown link (the picture showed as text), a '#' or '?' cut the path in either document."""
    return urllib.parse.quote(path)


def to_markdown(bs: list) -> str:
    md = []
    for b in bs:
        if b.kind in ("h1", "h2", "h3"):
            md += ["#" * int(b.kind[1]) + " " + b.content, ""]
        elif b.kind == "p":
            md += [b.content, ""]
        elif b.kind == "caption":
            md += [f"*{b.content}*", ""]
        elif b.kind == "ul":
            md += [f"- {x}" for x in b.content] + [""]
        elif b.kind == "img":
            md += [f"![{b.extra}]({_url(b.content)})", ""]
        elif b.kind == "table":
            head, rows = b.content
            md += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
            md += ["| " + " | ".join(_md_inline(c) for c in row) + " |" for row in rows] + [""]
    return "\n".join(md) + "\n"


_CSS = """body{font-family:sans-serif;max-width:1700px;margin:auto;padding:1em}
table{border-collapse:collapse;font-size:12px}td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}
td:first-child,th:first-child,td:nth-child(2),td:last-child{text-align:left}tr.failed td{color:#a00}
img{max-width:100%}h2{border-top:2px solid #444;padding-top:.5em}p.caption{font-style:italic;margin-top:0}"""


def _html_inline(text: str) -> str:
    e = html.escape(text)
    parts = e.split("**")
    return "".join(f"<b>{p}</b>" if i % 2 else p for i, p in enumerate(parts))


def to_html(bs: list) -> str:
    e = html.escape
    title = next((b.content for b in bs if b.kind == "h1"), "Lixel report")
    h = [f"<!doctype html><html><head><meta charset='utf-8'><title>{e(title)}</title><style>{_CSS}</style>"
         f"</head><body>"]
    scenes = [b.extra for b in bs if b.kind == "h2" and b.extra]
    for b in bs:
        if b.kind == "h1":
            h.append(f"<h1>{e(b.content)}</h1>")
        elif b.kind == "h2":
            anchor = f" id='{e(b.extra)}'" if b.extra else ""
            h.append(f"<h2{anchor}>{e(b.content)}</h2>")
            if b.content == "Summary":
                h.append("<p>Scenes: " + " · ".join(f"<a href='#{e(s)}'>{e(s)}</a>" for s in scenes) + "</p>")
        elif b.kind == "h3":
            h.append(f"<h3>{e(b.content)}</h3>")
        elif b.kind == "p":
            h.append(f"<p>{_html_inline(b.content)}</p>")
        elif b.kind == "caption":
            h.append(f"<p class='caption'>{_html_inline(b.content)}</p>")
        elif b.kind == "ul":
            h.append("<ul>" + "".join(f"<li>{_html_inline(x)}</li>" for x in b.content) + "</ul>")
        elif b.kind == "img":
            h.append(f"<img src='{e(_url(b.content))}' alt='{e(b.extra)}'>")
        elif b.kind == "table":
            head, rows = b.content
            h.append("<table><tr>" + "".join(f"<th>{e(c)}</th>" for c in head) + "</tr>")
            for row in rows:
                cls = " class='failed'" if any(str(c).startswith("failed") for c in row[2:3]) else ""
                h.append(f"<tr{cls}>" + "".join(f"<td>{e(c)}</td>" for c in row) + "</tr>")
            h.append("</table>")
    h.append("</body></html>")
    return "\n".join(h)


# --------------------------------------------------------------------------- writing

def _strip(obj):
    """JSON-able copy without images and private keys."""
    if isinstance(obj, dict):
        return {k: _strip(v) for k, v in obj.items() if not k.startswith("_") and k != "overlays"}
    if isinstance(obj, (list, tuple)):
        return [_strip(v) for v in obj]
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    if isinstance(obj, float) and (math.isinf(obj) or math.isnan(obj)):
        return str(obj)
    if isinstance(obj, Path):
        return str(obj)
    return obj


def _overlay_caption(shot, scene: dict) -> str:
    if shot.kind == "texels":
        text = (f"The texel grid on the receivers, seen from the scene camera: every checker square is one texel of "
                f"a {shot.size}² map (a coarse map, so that single texels are visible). Where squares are small, "
                f"the map spends many texels; {' and '.join(t.split(',')[0] for t, _ in shot.panels)} side by side "
                f"show where each puts its texels.")
    elif shot.kind == "heatmap":
        text = (f"The footprint heatmap from the scene camera at {shot.size}²: screen pixels spanned by one texel "
                f"(the viewport overlay's own shader), red where texels are larger than pixels (blocky edges), "
                f"green at one pixel per texel, blue where texels are finer than pixels.")
    else:
        text = (f"{shot.method} at {shot.size}² from an outside observer: the camera's view frustum (cyan), "
                f"the light frusta (yellow), the intersection body B (orange), the warp frustum P (magenta) with "
                f"its projection centre and V_P, over the heatmap on every receiver (grey where no map serves).")
        if shot.notes:
            text += " " + "; ".join(n[0].upper() + n[1:] for n in shot.notes) + "."
    return text + " Drawn off-screen by the viewport's draw code (addon/ui/overlays.py)."


def write_figures(result: dict, out: Path, progress=None) -> dict:
    """The figures of every scene under ``out``; returns {scene: {section: file or [(file, caption)]}}."""
    import contextlib
    pics: dict = {}
    for scene in result["scenes"]:
        if scene.get("status") != "ok":
            continue
        ctx = progress.step("figures", f"{scene['name']}: figures", scene["name"]) if progress else \
            contextlib.nullcontext()
        with ctx:
            d = out / scene["name"]
            d.mkdir(parents=True, exist_ok=True)
            made = {}
            for section, fn, fname in FIGURES:
                try:
                    fn(scene, d / fname)
                    made[section] = f"{scene['name']}/{fname}"
                except Exception as exc:  # noqa: BLE001 - a figure that fails is reported in its section
                    made[section] = None
                    scene.setdefault("figure_errors", {})[section] = f"{type(exc).__name__}: {exc}"
            shots = []
            for shot in scene.get("overlays") or []:
                fname = OVERLAY_FILES[shot.kind]
                try:
                    figures.overlay(shot, d / fname, scene["name"])
                    shots.append((f"{scene['name']}/{fname}", _overlay_caption(shot, scene)))
                except Exception as exc:  # noqa: BLE001
                    scene.setdefault("figure_errors", {})[f"overlay {shot.kind}"] = f"{type(exc).__name__}: {exc}"
            made["Overlays"] = shots
            scene["overlay_files"] = [f for f, _ in shots]
            pics[scene["name"]] = made
    return pics


README_SIZE = 2048
"""The map size of the README's comparison picture (the run's size nearest to it)."""
README_TEXELS_SCENE = "terrain"
"""The scene whose texel-grid snapshot the README shows: its open ground shows single texels best."""


def _with_results(scene: dict) -> bool:
    return scene.get("status") == "ok" and any(m.get("status") == "ok" for m in scene.get("methods", []))


def readme_pictures(result: dict, out: Path, folder: Path) -> list:
    """The README's pictures: the comparison of the first scene with results
    (its error images at the size nearest README_SIZE that EEVEE also ran at)
    and a copy of its observer snapshot, and the texel-grid snapshot of
    README_TEXELS_SCENE (else of the first scene). Returns the paths written."""
    import shutil
    scenes = [s for s in result["scenes"] if _with_results(s)]
    if not scenes:
        return []
    first = scenes[0]
    ok = [m for m in first["methods"] if m.get("status") == "ok"]
    sizes = sorted({m["size"] for m in ok})
    eevee = [p["size"] for p in first["peers"] if p["method"] == "eevee" and p.get("size") in sizes]
    size = min(eevee or sizes, key=lambda s: abs(s - README_SIZE))
    methods = list(dict.fromkeys(m["method"] for m in ok))
    preferred = [m for m in README_METHODS if m in methods] or methods[:3]
    folder.mkdir(parents=True, exist_ok=True)
    written = [figures.comparison(first, preferred, size, folder / "comparison.png")]
    texels = next((s for s in scenes if s["name"] == README_TEXELS_SCENE), first)
    for scene, kind in ((first, "observer"), (texels, "texels")):
        for f in scene.get("overlay_files", []):
            if kind in f:
                shutil.copyfile(out / f, folder / Path(f).name)
                written.append(folder / Path(f).name)
    return written


def write(result: dict, out: Path, progress=None) -> dict:
    """Figures, report.html, report.md and report.json under ``out``; returns the paths."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    pics = write_figures(result, out, progress)
    bs = blocks(result, pics)
    paths = {"html": out / "report.html", "md": out / "report.md", "json": out / "report.json"}
    paths["json"].write_text(json.dumps(_strip(result), indent=1))
    paths["md"].write_text(to_markdown(bs))
    paths["html"].write_text(to_html(bs))
    return paths
