"""Draw Lixel's viewport overlays off-screen and save them as PNG, for any scene:
from the scene camera and from an outside observer that sees the whole setup
(view frustum, light frusta, the intersection body B, the warp frustum with its
projection centre, V_P and B's middle vector, the texel grid or the footprint
heatmap on the receivers). The drawing is the viewport's own code
(addon/ui/overlays.py), so the pictures show what the viewport shows.

    blender -b scene.blend --python scripts/overlay_snapshot.py -- --output-dir snaps/
    python scripts/overlay_snapshot.py scene.blend --output-dir snaps/ [--method lispsm] [--size 64]
        [--views camera,observer] [--camera-overlays texels] [--observer-overlays body,frusta,warp,footprint]

Writes OUTPUT_DIR/overlay_camera.png and/or OUTPUT_DIR/overlay_observer.png.
Overlays: body, frusta, warp, texels, footprint. A coarse --size (32..128)
makes single texels visible in the texel grid.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _lixel_script as ls  # noqa: E402

VIEWS = ("camera", "observer")
OVERLAYS = ("body", "frusta", "warp", "texels", "footprint")


def parser():
    p = ls.base_parser("overlay_snapshot.py", "Draw Lixel's viewport overlays off-screen and save them as PNG.")
    p.add_argument("--output-dir", "-o", required=True, help="directory for the PNG files")
    p.add_argument("--method", help="the warp method (default: the scene's)")
    p.add_argument("--views", default="camera,observer", help="camera and/or observer (default: both)")
    p.add_argument("--camera-overlays", default="texels", help="overlays drawn from the camera (default: texels)")
    p.add_argument("--observer-overlays", default="body,frusta,warp,footprint",
                   help="overlays drawn from the observer (default: body,frusta,warp,footprint)")
    p.add_argument("--width", type=int, default=960, help="picture width in pixels (default 960)")
    return p


def main(argv=None):
    p = parser()
    args = ls.parse(p, argv)
    views = ls.names_option(p, "--views", args.views, VIEWS)
    overlays = {"camera": ls.names_option(p, "--camera-overlays", args.camera_overlays, OVERLAYS),
                "observer": ls.names_option(p, "--observer-overlays", args.observer_overlays, OVERLAYS)}
    if not 64 <= args.width <= 8192:
        p.error(f"--width {args.width}: use 64..8192 pixels")
    with ls.Session(args) as s:
        methods = s.module("addon.warp.methods").METHODS
        if args.method is not None and args.method not in methods:
            p.error(f"--method {args.method!r}: choose one of {', '.join(methods)}")
        snapshot = s.module("addon.ui.snapshot")
        renders = s.module("addon.ui.renders")
        s.module("addon.gpu.context").ensure_gpu_context()
        scene = s.scene()
        st = s.state(scene, s.settings(scene, args.method))
        os.makedirs(args.output_dir, exist_ok=True)
        for view in views:
            if view == "camera":
                w, h = renders.fit_resolution(st.view.resolution, args.width)
                vp, notes = snapshot.camera_view_projection(st.view), []
            else:
                w, h = args.width, max(1, round(args.width * 0.625))
                vp, notes = snapshot.observer_view_projection(st.geometry, st.view, w / h, scene=scene)
            img = snapshot.draw_snapshot(scene, st, snapshot.OverlayFlags.of(overlays[view]), vp, (w, h))
            path = os.path.join(args.output_dir, f"overlay_{view}.png")
            renders.save_image(img, path, linear=False)  # the overlays draw display colours
            print(f"wrote {path} ({st.method_used}, {len(st.setup.maps)} map(s), {', '.join(overlays[view])})")
            for note in notes:
                print(f"  note: {note}")
        return 0


if __name__ == "__main__":
    ls.run(main)
