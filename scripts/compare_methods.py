"""Compare every Lixel method on a scene's camera view: a table of θ, γ, n_opt,
λ, maps and texel footprints, one picture per method and a mosaic.

    blender -b scene.blend --python scripts/compare_methods.py -- --output-dir out/
    python scripts/compare_methods.py scene.blend --output-dir out/ [--no-render]

Writes OUTPUT_DIR/comparison.json (every method's row and setup in the CLI's
format), and unless --no-render, OUTPUT_DIR/<method>.png and comparison.png.
"""
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _lixel_script as ls  # noqa: E402


def parser():
    p = ls.base_parser("compare_methods.py", "Compare every Lixel method on the camera view.")
    p.add_argument("--output-dir", "-o", required=True, help="directory for the pictures and comparison.json")
    p.add_argument("--methods", help="comma-separated methods (default: all)")
    p.add_argument("--longest", type=int, default=480, help="longer side of each picture in pixels (default 480)")
    p.add_argument("--no-render", action="store_true", help="only the numbers (no GPU needed)")
    return p


def main(argv=None):
    p = parser()
    args = ls.parse(p, argv)
    if not 16 <= args.longest <= 16384:
        p.error(f"--longest {args.longest}: use 16..16384 pixels")
    with ls.Session(args) as s:
        all_methods = list(s.module("addon.warp.methods").METHODS)
        methods = all_methods if args.methods is None else ls.names_option(p, "--methods", args.methods, all_methods)
        live = s.module("addon.ui.live")
        scene = s.scene()
        st = s.state(scene, s.settings(scene, "uniform"))
        rows = live.compare_methods(st, methods)
        print(live.comparison_table(rows, scene))
        os.makedirs(args.output_dir, exist_ok=True)
        camera = s.objects(scene)[0] or s.module("addon.scene.describe").render_camera(scene)
        doc = {"scene": scene.name, "camera": camera.name, "light": st.light_name,
               "methods": {}}
        for row in rows:
            entry = {k: v for k, v in row.items() if k not in ("setup", "method")}
            if "setup" in row:
                entry.update(s.module("addon.cli.output").setup_json(row["setup"]))
            doc["methods"][row["method"]] = entry
        if not args.no_render:
            renders = s.module("addon.ui.renders")
            depsgraph = s.bpy.context.evaluated_depsgraph_get()
            geometry = renders.scene_geometry(depsgraph)
            res = renders.fit_resolution(st.view.resolution, args.longest)
            images, labels = [], []
            for row in rows:
                if "setup" not in row:
                    continue
                out = renders.render_state(st, depsgraph, res, setup=row["setup"], geometry=geometry, read={"combined"})
                path = os.path.join(args.output_dir, f"{row['method']}.png")
                renders.save_image(out.combined, path, view_of=scene)
                images.append(out.combined)
                render_ms = sum(out.timings.values()) * 1000
                labels.append(renders.method_label(row, scene, render_ms))
                doc["methods"][row["method"]]["picture"] = os.path.basename(path)
                doc["methods"][row["method"]]["render_ms"] = render_ms
            if images:
                renders.save_image(renders.mosaic(images, columns=min(3, len(images)), labels=labels),
                                   os.path.join(args.output_dir, "comparison.png"), view_of=scene)
        # whole or not at all: a failed write leaves the file that was there
        s.module("addon.cli.output").write_text(os.path.join(args.output_dir, "comparison.json"),
                                                json.dumps(doc, indent=2))
        return 0


if __name__ == "__main__":
    ls.run(main)
