"""Export Lixel's light matrices and diagnostics for every frame of a camera
animation, in the command line's JSON format per frame.

    blender -b scene.blend --python scripts/export_animation.py -- --output anim.json --frames 1:48
    python scripts/export_animation.py scene.blend --output anim.json [--method lispsm] [--frames 1:48:2]

Output: {"scene", "method", "frames": [{"frame": f, "maps": [...], "diagnostics": {...}} |
{"frame": f, "error": "..."}]}. With ``--output -`` standard output carries the
JSON only (everything else goes to standard error; with the Blender binary add
``-q`` so Blender's own status lines, printed before the script runs, stay out). A frame Lixel cannot handle (e.g. the camera
is degenerate) is recorded with its error, a frame with nothing to shadow (the
camera looks at the sky) as the command line reports an empty body; the exit
status is 0 unless every frame failed, when nothing is written (a file already
there is kept).
"""
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _lixel_script as ls  # noqa: E402


def parser():
    p = ls.base_parser("export_animation.py", "Export light matrices for each frame of the animation.")
    p.add_argument("--output", "-o", required=True, help="JSON file to write ('-' for standard output)")
    p.add_argument("--method", help="the warp method (default: the scene's)")
    p.add_argument("--frames", help="START:END[:STEP] inclusive (default: the scene's frame range)")
    return p


def frame_range(p, text, scene):
    if text is None:
        return range(scene.frame_start, scene.frame_end + 1, max(1, scene.frame_step))
    try:
        parts = [int(v) for v in text.split(":")]
    except ValueError:
        p.error(f"--frames {text!r}: use START:END or START:END:STEP with whole numbers")
    if len(parts) not in (2, 3) or (len(parts) == 3 and parts[2] < 1) or parts[1] < parts[0]:
        p.error(f"--frames {text!r}: use START:END[:STEP] with START <= END and STEP >= 1")
    ls.check_frames(p, "--frames", repr(text), parts[0], parts[1])
    return range(parts[0], parts[1] + 1, parts[2] if len(parts) == 3 else 1)


def main(argv=None):
    p = parser()
    args = ls.parse(p, argv)
    if args.frames is not None:
        frame_range(p, args.frames, None)  # bad ranges fail before the file is loaded
    with ls.data_stdout(args.output == "-") as data, ls.Session(args) as s:
        methods = s.module("addon.warp.methods").METHODS
        if args.method is not None and args.method not in methods:
            p.error(f"--method {args.method!r}: choose one of {', '.join(methods)}")
        live = s.module("addon.ui.live")
        scene = s.scene()
        settings = s.settings(scene, args.method)
        frames = frame_range(p, args.frames, scene)
        s.objects(scene)   # a --camera/--light that is not there: said at once, no file written (each frame said it)
        doc = {"scene": scene.name, "method": settings.method, "frames": []}
        output = s.module("addon.cli.output")
        failed = 0
        for f in frames:
            scene.frame_set(f)
            try:
                st = s.state(scene, settings, empty_ok=True)
            except ls.ScriptError as exc:
                doc["frames"].append({"frame": f, "error": str(exc)})
                failed += 1
                continue
            if st.empty_body:   # the camera sees nothing to shadow (the sky), as the command line reports it
                method = s.module("addon.ui.live").resolve_method(settings.method)[0]
                doc["frames"].append({"frame": f, **output.empty_body_json(method, st.empty_body)})
                continue
            doc["method"] = st.method_used
            doc["frames"].append({"frame": f, **output.setup_json(st.setup)})
        live.clear()
        if failed == len(doc["frames"]):   # an export already there is kept, not replaced by errors alone
            raise ls.ScriptError(f"no frame could be computed, nothing written: "
                                 f"{doc['frames'][0]['error'] if doc['frames'] else 'empty range'}")
        text = json.dumps(doc, indent=1)
        if args.output == "-":
            print(text, file=data)
        else:
            output.write_text(args.output, text + "\n")   # whole or not at all
            print(f"lixel: {len(doc['frames']) - failed} of {len(doc['frames'])} frames exported to {args.output}")
        return 0


if __name__ == "__main__":
    ls.run(main)
