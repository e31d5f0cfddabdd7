"""Write the report: ``report.html`` and its Markdown twin ``report.md``, the
figures under ``<scene>/`` and the numbers in ``report.json``."""
from __future__ import annotations

import html
import json
import math
from pathlib import Path

import numpy as np

from . import figures

README_METHODS = ("uniform", "lispsm", "gmnpr", "plane_optimal")
"""Methods shown in the README picture (when run), with the peers and the truth."""

SECTIONS = ("Renders", "Shadow maps", "Footprint", "Errors", "Speed against error", "Table")
"""The sections every scene gets, in order (the report test checks them)."""

DEFINITIONS = [
    ("Ground truth", "exact hard shadows per pixel: the first hit of the camera ray in a BVH of the scene's "
                     "triangles, then a ray from that point to the light."),
    ("Counted pixels", "a surface is visible, it faces the light and (spot) lies in the cone; Lixel pixels where "
                       "the rasterized surface differs from the ray-cast one (silhouettes) are left out and counted "
                       "as 'excluded'."),
    ("error %", "misclassified counted pixels; false shadow = dark where the truth is lit, false light = the reverse; "
                "edge % = the same within the band around true shadow edges."),
    ("flicker %", "over the camera animation, of the pixel transitions where the ground truth keeps its state, the "
                  "fraction where the method's state changes."),
    ("footprint", "screen pixels spanned by one texel in its worst direction (largest singular value of the "
                  "texel-to-pixel Jacobian on the surface); above 1 means blocky shadow edges."),
    ("m_min", "Lloyd's physical limit: the smallest maximum perspective footprint any parameterization can reach "
              "with the method's texel count N, sqrt(N_min / N). persp max/m_min: the method's largest perspective "
              "footprint (pixel density K/z² needed over texel density given, both on the plane perpendicular to the "
              "light, so the surface orientation drops out) over that limit; 1 is the best possible over the whole "
              "frustum (a method can go below 1 on the visible part only)."),
    ("peers", "EEVEE and Cycles with one white diffuse material, black world, the scene's light only: the render "
              "with shadows divided by the one without, below 0.5 = shadow. Known: Cycles under the chess scene's "
              "spot light darkens some board pixels near the camera that both this ground truth and Blender's "
              "own scene.ray_cast see lit (cause not found)."),
    ("times", "Lixel: CPU setup (warp matrices and body), depth pass, shading pass on the GPU (llvmpipe here); "
              "peers: one render with shadows, made after a shadowless one that absorbs EEVEE's shader compilation."),
]


def _pct(x):
    return "" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{100 * x:.2f}"


def _num(x, fmt="{:.2f}"):
    if x is None:
        return ""
    if isinstance(x, float) and (math.isnan(x) or math.isinf(x)):
        return "∞" if (isinstance(x, float) and math.isinf(x)) else ""
    return fmt.format(x)


TABLE_HEAD = ["method", "map", "status", "error %", "false shadow", "false light", "edge %", "flicker %",
              "fp max", "fp p95", "fp mean", "fp>1 %", "m_min", "persp max/m_min", "setup ms", "depth ms",
              "shading ms", "total ms", "excluded"]


def table_rows(scene: dict) -> list[list[str]]:
    rows = []
    for r in scene["methods"] + scene["peers"]:
        size = f"{r['size']}²" if "size" in r else ("" if r.get("status") != "ok" else f"{r.get('samples', '')} spp")
        if r.get("status") != "ok":
            rows.append([r["method"], size, "failed: " + r.get("reason", "")] + [""] * (len(TABLE_HEAD) - 3))
            continue
        e, fp, t = r["errors"], r.get("footprint", {}), r.get("timings", {})
        fl = r.get("flicker")
        rows.append([
            r["method"], size if "size" not in r else f"{r['size']}² ×{len(r.get('maps', []))}", "ok",
            _pct(e["error_rate"]), str(e["false_shadow"]), str(e["false_light"]), _pct(e["band_error_rate"]),
            _pct(fl["rate"]) if fl else "",
            _num(fp.get("max")), _num(fp.get("p95")), _num(fp.get("mean")), _pct(fp.get("frac_above_1")),
            _num(r.get("m_min"), "{:.3f}"), _num(r.get("max_over_limit"), "{:.1f}"),
            _num(1000 * t["cpu_setup"], "{:.1f}") if "cpu_setup" in t else "",
            _num(1000 * t["depth_pass"], "{:.1f}") if "depth_pass" in t else "",
            _num(1000 * t["shading"], "{:.1f}") if "shading" in t else "",
            _num(r["total_ms"], "{:.0f}"), str(r.get("excluded_pixels", "")),
        ])
    return rows


def _facts(scene: dict) -> list[str]:
    v = scene.get("view", {})
    gt = scene.get("ground_truth", {})
    facts = [f"{scene.get('triangles', 0):,} triangles in {scene.get('instances', 0):,} instances",
             f"{scene['resolution'][0]}×{scene['resolution'][1]} pixels, frames {scene['frames'][0]}–{scene['frames'][-1]}",
             f"{scene.get('light', '?')} light; camera fov {v.get('fov_x_deg', 0):.1f}°×{v.get('fov_y_deg', 0):.1f}°, "
             f"near {v.get('near', 0):g}, far {v.get('far', 0):g}",
             f"ground truth: {gt.get('valid_pixels', 0):,} counted pixels, {100 * gt.get('shadow_fraction', 0):.1f}% in "
             f"shadow, {gt.get('seconds_per_frame', 0):.2f} s a frame"]
    if scene.get("n_min"):
        facts.append(f"Lloyd's N_min = {scene['n_min']:,.0f} texels (a {math.sqrt(scene['n_min']):,.0f}² map "
                     f"at footprint 1)")
    elif scene.get("n_min_reason"):
        facts.append(f"Lloyd's N_min: not defined here ({scene['n_min_reason']})")
    front = pareto_names(scene)
    if front:
        facts.append("Pareto front (fastest first): " + ", ".join(front))
    return facts


def pareto_names(scene: dict) -> list[str]:
    recs = [r for r in scene["methods"] + scene["peers"] if r.get("status") == "ok"]
    pts = [(r["total_ms"], r["errors"]["error_rate"]) for r in recs]
    return [f"{recs[i]['method']}" + (f" {recs[i]['size']}" if "size" in recs[i] else "")
            for i in figures.pareto_front(pts)]


def _strip(obj):
    """JSON-able copy without images."""
    if isinstance(obj, dict):
        return {k: _strip(v) for k, v in obj.items() if not k.startswith("_")}
    if isinstance(obj, (list, tuple)):
        return [_strip(v) for v in obj]
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    if isinstance(obj, float) and (math.isinf(obj) or math.isnan(obj)):
        return str(obj)
    return obj


def write(result: dict, out: Path, progress=print, readme_picture: Path | None = None) -> dict:
    """Figures, report.html, report.md and report.json under ``out``; returns the paths."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    pics: dict = {}
    for scene in result["scenes"]:
        if scene.get("status") != "ok":
            continue
        d = out / scene["name"]
        d.mkdir(exist_ok=True)
        made = {}
        for section, fn, fname in (("Renders", figures.renders, "renders.png"),
                                   ("Shadow maps", figures.shadow_maps, "shadow_maps.png"),
                                   ("Footprint", figures.footprints, "footprint.png"),
                                   ("Errors", figures.errors, "errors.png"),
                                   ("Speed against error", figures.speed_error, "speed_error.png")):
            try:
                fn(scene, d / fname)
                made[section] = f"{scene['name']}/{fname}"
            except Exception as exc:  # noqa: BLE001 - a figure that fails is reported in its section
                made[section] = None
                scene.setdefault("figure_errors", {})[section] = f"{type(exc).__name__}: {exc}"
        pics[scene["name"]] = made
        progress(f"figures for {scene['name']} written")
    paths = {"html": out / "report.html", "md": out / "report.md", "json": out / "report.json"}
    paths["json"].write_text(json.dumps(_strip(result), indent=1))
    paths["md"].write_text(_markdown(result, pics))
    paths["html"].write_text(_html(result, pics))
    if readme_picture is not None:
        for scene in result["scenes"]:
            if scene.get("status") == "ok" and any(m.get("status") == "ok" for m in scene["methods"]):
                sizes = sorted({m["size"] for m in scene["methods"] if m.get("status") == "ok"})
                size = sizes[len(sizes) // 2]
                readme_picture.parent.mkdir(parents=True, exist_ok=True)
                methods = list(dict.fromkeys(m["method"] for m in scene["methods"]))
                preferred = [m for m in README_METHODS if m in methods]
                figures.comparison(scene, preferred or methods[:4], size, readme_picture)
                paths["picture"] = readme_picture
                break
    return paths


def summary_rows(result: dict) -> list[list[str]]:
    """One row per scene: for each map size the Lixel method with the fewest errors
    (its error % and time), then each peer."""
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
                row.append(f"{b['method']} {100 * b['errors']['error_rate']:.2f}% ({b['total_ms']:.0f} ms)")
            else:
                row.append("")
        for peer in ("eevee", "cycles"):
            p = next((x for x in scene["peers"] if x["method"] == peer), None)
            row.append("" if p is None else (f"{100 * p['errors']['error_rate']:.2f}% ({p['total_ms'] / 1000:.1f} s)"
                                             if p.get("status") == "ok" else "failed"))
        rows.append(row)
    return [["scene"] + [f"best at {s}²" for s in sizes] + ["EEVEE", "Cycles"]] + rows


def _header(result: dict) -> tuple[str, list[str]]:
    o = result["options"]
    title = "Lixel: speed against error"
    lines = [f"Blender {result['blender']}; {'quick run' if o['quick'] else 'full run'}: scenes "
             f"{', '.join(o['scenes'])}; methods {', '.join(o['methods'])}; map sizes "
             f"{', '.join(str(s) for s in o['sizes'])}; {o['resolution'][0]}×{o['resolution'][1]} pixels; "
             f"{o['frames']} frame(s) of camera animation; EEVEE {o['eevee_samples']} spp, Cycles {o['cycles_samples']} spp "
             f"(direct light only). Took {result.get('seconds', 0):.0f} s."]
    return title, lines


def _markdown(result: dict, pics: dict) -> str:
    title, intro = _header(result)
    md = [f"# {title}", ""] + intro + ["", "## How to read it", ""]
    md += [f"- **{k}**: {v}" for k, v in DEFINITIONS] + [""]
    summary = summary_rows(result)
    md += ["## Summary", "", "| " + " | ".join(summary[0]) + " |", "|" + "---|" * len(summary[0])]
    md += ["| " + " | ".join(c.replace("|", "/") for c in row) + " |" for row in summary[1:]] + [""]
    for scene in result["scenes"]:
        md.append(f"## Scene: {scene['name']}")
        md.append("")
        if scene.get("status") != "ok":
            md += [f"**Failed**: {scene.get('reason', '')}", ""]
            continue
        md += [f"- {f}" for f in _facts(scene)] + [""]
        for section in SECTIONS[:-1]:
            md.append(f"### {section}")
            md.append("")
            pic = pics.get(scene["name"], {}).get(section)
            md.append(f"![{section}]({pic})" if pic else f"(figure failed: {scene.get('figure_errors', {}).get(section, '')})")
            md.append("")
        md += ["### Table", "", "| " + " | ".join(TABLE_HEAD) + " |", "|" + "---|" * len(TABLE_HEAD)]
        for row in table_rows(scene):
            md.append("| " + " | ".join(c.replace("|", "/") for c in row) + " |")
        md.append("")
    return "\n".join(md) + "\n"


_CSS = """body{font-family:sans-serif;max-width:1600px;margin:auto;padding:1em}
table{border-collapse:collapse;font-size:12px}td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}
td:first-child,th:first-child{text-align:left}tr.failed td{color:#a00}img{max-width:100%}
h2{border-top:2px solid #444;padding-top:.5em}"""


def _html(result: dict, pics: dict) -> str:
    title, intro = _header(result)
    e = html.escape
    h = [f"<!doctype html><html><head><meta charset='utf-8'><title>{e(title)}</title><style>{_CSS}</style></head><body>",
         f"<h1>{e(title)}</h1>"] + [f"<p>{e(x)}</p>" for x in intro]
    h.append("<h2>How to read it</h2><ul>" + "".join(f"<li><b>{e(k)}</b>: {e(v)}</li>" for k, v in DEFINITIONS) + "</ul>")
    summary = summary_rows(result)
    h.append("<h2>Summary</h2><table><tr>" + "".join(f"<th>{e(c)}</th>" for c in summary[0]) + "</tr>"
             + "".join("<tr>" + "".join(f"<td>{e(c)}</td>" for c in row) + "</tr>" for row in summary[1:])
             + "</table>")
    h.append("<p>Scenes: " + " · ".join(f"<a href='#{e(s['name'])}'>{e(s['name'])}</a>" for s in result["scenes"]) + "</p>")
    for scene in result["scenes"]:
        h.append(f"<h2 id='{e(scene['name'])}'>Scene: {e(scene['name'])}</h2>")
        if scene.get("status") != "ok":
            h.append(f"<p class='failed'><b>Failed</b>: {e(scene.get('reason', ''))}</p>")
            continue
        h.append("<ul>" + "".join(f"<li>{e(f)}</li>" for f in _facts(scene)) + "</ul>")
        for section in SECTIONS[:-1]:
            h.append(f"<h3>{e(section)}</h3>")
            pic = pics.get(scene["name"], {}).get(section)
            h.append(f"<img src='{e(pic)}' alt='{e(section)}'>" if pic else
                     f"<p>(figure failed: {e(scene.get('figure_errors', {}).get(section, ''))})</p>")
        h.append("<h3>Table</h3><table><tr>" + "".join(f"<th>{e(c)}</th>" for c in TABLE_HEAD) + "</tr>")
        for row in table_rows(scene):
            cls = " class='failed'" if row[2].startswith("failed") else ""
            h.append(f"<tr{cls}>" + "".join(f"<td>{e(c)}</td>" for c in row) + "</tr>")
        h.append("</table>")
    h.append("</body></html>")
    return "\n".join(h)
