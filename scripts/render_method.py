"""Render a scene's camera view with Lixel's shadows, using one method.

    blender -b scene.blend --python scripts/render_method.py -- --method lispsm --output out.png
    python scripts/render_method.py scene.blend --method lispsm --output out.png [--json setup.json]

Writes the shaded picture, optionally the shadow mask and the first shadow map, each in the format its file
name's ending names (PNG, OpenEXR, JPEG or TIFF; PNG without one), and the setup (matrices + diagnostics, the
CLI's JSON). The picture and the mask keep the scene's Render Region as F12 does (cut to it with Crop).

The picture is F12's (the Lixel engine's) but for a few shadow-edge pixels: F12 fits the maps to what its GPU
pre-pass sees, this script to a ray cast against the objects' boxes (the sidebar's live state, which --json writes),
so their maps differ a little once a scene is not the plainest (3 of 5184 pixels with an Array modifier, 2 with a
camera shift: tests/blender/test_scripts.py). For F12's exact pixels render with F12 (blender -b FILE -f N with the
Lixel engine). A view with nothing to shadow (the camera looks at the sky) is drawn unshadowed with F12's warning;
its --json is the command line's empty body, and it has no map to write.
"""
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _lixel_script as ls  # noqa: E402


def parser():
    p = ls.base_parser("render_method.py", "Render the camera view with Lixel's warped shadow maps.")
    p.add_argument("--method", help="the warp method (default: the scene's); see --list-methods")
    p.add_argument("--output", "-o", help="picture file for the shaded picture (.png, .exr, .jpg or .tif: the "
                                          "format its ending names; .exr keeps values above 1)")
    p.add_argument("--shadow-output", help="picture file for the shadow mask (white = shadowed)")
    p.add_argument("--map-output", help="picture file for the first shadow map's depth")
    p.add_argument("--json", help="write the setup (matrices + diagnostics, the CLI's format) to this file")
    p.add_argument("--resolution", help="WxH pixels, framed as Blender frames that output size (default: the "
                                        "scene's render size)")
    p.add_argument("--frame", type=int, help="frame to render (default: the current frame)")
    p.add_argument("--list-methods", action="store_true", help="print the available methods and exit")
    return p


MIN_SIDE = 4
"""The smallest render side Blender takes (``RenderSettings.resolution_x``'s minimum, 4.2 and 5.0)."""


def parse_resolution(p, text):
    if text is None:
        return None
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        p.error(f"--resolution {text!r}: use WxH, e.g. 640x360")
    if not (MIN_SIDE <= w <= 16384 and MIN_SIDE <= h <= 16384):   # Blender raises a smaller side to 4 unasked
        p.error(f"--resolution {text}: each side must be {MIN_SIDE}..16384 pixels")
    return w, h


def main(argv=None):
    p = parser()
    args = ls.parse(p, argv)
    resolution = parse_resolution(p, args.resolution)
    if args.frame is not None:
        ls.check_frames(p, "--frame", args.frame, args.frame)
    if not args.list_methods and not (args.output or args.json or args.shadow_output or args.map_output):
        p.error("nothing to write: give --output (and/or --json, --shadow-output, --map-output)")
    with ls.Session(args) as s:
        methods = s.module("addon.warp.methods").METHODS
        if args.list_methods:
            print("\n".join(methods))
            return 0
        if args.method is not None and args.method not in methods:
            p.error(f"--method {args.method!r}: choose one of {', '.join(methods)}")
        renders = s.module("addon.ui.renders")
        for path in (args.output, args.shadow_output, args.map_output):
            if path:
                renders.image_format(path)   # an ending Lixel does not write: said before rendering
        scene = s.scene()
        if resolution is not None:  # rendered as Blender renders that output size (never saved)
            scene.render.resolution_x, scene.render.resolution_y = resolution
            scene.render.resolution_percentage = 100
        if args.frame is not None:
            scene.frame_set(args.frame)
        st = s.state(scene, s.settings(scene, args.method), empty_ok=True)
        setup, method = st.setup, st.method_used
        if st.empty_body:   # as F12: the frame unshadowed, with a warning (it was refused, where F12 rendered it)
            method = s.module("addon.ui.live").resolve_method(st.settings.method)[0]
            setup = s.module("addon.render.engine").no_shadow_setup(method)
            print(f"lixel: warning: no shadows in this view ({st.empty_body}), as F12 renders it", file=sys.stderr)
        elif st.note:
            print(f"lixel: warning: {st.note}", file=sys.stderr)
        if args.json:
            output = s.module("addon.cli.output")    # whole or not at all: a failed write leaves what was there
            doc = output.empty_body_json(method, st.empty_body) if st.empty_body else output.setup_json(setup)
            output.write_text(args.json, json.dumps(doc, indent=2))
        if args.output or args.shadow_output or args.map_output:
            depsgraph = s.bpy.context.evaluated_depsgraph_get()
            res = renders.render_state(st, depsgraph, st.view.resolution, setup=setup)
            # a light with Shadow off draws no map (as F12): its 1x1 stand-in was written as the map
            shadow_off = s.module("addon.scene.describe").shadow_off
            unshadowed = st.empty_body or shadow_off(renders.state_light(st, depsgraph))
            if args.output:
                renders.save_image(renders.within_border(scene.render, res.combined), args.output, view_of=scene)
            if args.shadow_output:
                import numpy as np
                m = np.asarray(res.shadow_mask, dtype=np.float32)
                renders.save_image(renders.within_border(scene.render, np.dstack([m, m, m, np.ones_like(m)])),
                                   args.shadow_output)
            if args.map_output and unshadowed:
                print(f"lixel: warning: no shadow map to write to {args.map_output} ({unshadowed})", file=sys.stderr)
            elif args.map_output and res.shadow_maps:
                renders.save_image(renders.depth_to_rgba(res.shadow_maps[0]), args.map_output)
            t = res.timings
            maps = 0 if st.empty_body else len(setup.maps)
            print(f"lixel: {method}: {maps} map(s) of light '{st.light_name}', "
                  f"{sum(t.values()) * 1000:.0f} ms render ({', '.join(f'{k} {v * 1000:.0f}' for k, v in t.items())})")
        return 0


if __name__ == "__main__":
    ls.run(main)
