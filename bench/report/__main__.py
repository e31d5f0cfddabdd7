"""``make demo`` = ``python -m bench.report``: the speed-against-error report.

    python -m bench.report                       # every sample scene, every method (about 10 minutes)
    python -m bench.report --quick               # the 2-minute version, every section
    python -m bench.report --scene chess --methods uniform,lispsm --sizes 1024,4096

Writes out/report.html, out/report.md, out/report.json and out/<scene>/*.png.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _scratch_env() -> None:
    # Keep Blender's and Mesa's caches and user resources out of $HOME (before bpy loads).
    scratch = Path(tempfile.gettempdir()) / "lixel-report"
    os.environ.setdefault("XDG_CACHE_HOME", str(scratch / "xdg"))
    os.environ.setdefault("BLENDER_USER_RESOURCES", str(scratch / "blender-user"))


def _csv(text: str) -> list[str]:
    return [t.strip() for t in text.split(",") if t.strip()]


def parse(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="python -m bench.report", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="small resolution, fewer frames and sizes (about 2 minutes)")
    ap.add_argument("--scene", "--scenes", dest="scenes", type=_csv, default=None,
                    help="comma-separated scene names or .blend paths (default: all sample scenes)")
    ap.add_argument("--methods", type=_csv, default=None, help="comma-separated warp methods (default: all)")
    ap.add_argument("--sizes", type=lambda s: [int(x) for x in _csv(s)], default=None,
                    help="comma-separated shadow-map sizes in texels per side")
    ap.add_argument("--peers", type=_csv, default=None, help="eevee,cycles (default both; 'none' for neither)")
    ap.add_argument("--resolution", type=lambda s: tuple(int(x) for x in s.lower().split("x")), default=None,
                    help="render size WxH")
    ap.add_argument("--frames", type=int, default=None, help="frames of camera animation for flicker")
    ap.add_argument("--eevee-samples", type=int, default=None)
    ap.add_argument("--out", type=Path, default=ROOT / "out")
    ap.add_argument("--readme-picture", type=Path, default=None,
                    help="also write the comparison picture here (e.g. docs/images/comparison.png)")
    return ap.parse_args(argv)


def main(argv=None) -> int:
    args = parse(argv)
    _scratch_env()
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    import bpy  # noqa: F401 - loads Blender before anything uses mathutils

    from addon.warp import METHODS
    from sample_blends.scenes import BUILDERS
    from . import document
    from .run import DEFAULT_SIZES, QUICK_SIZES, Options, full_defaults, quick_defaults, run

    base = quick_defaults() if args.quick else full_defaults()
    methods = args.methods or list(METHODS)
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        print(f"unknown method(s) {', '.join(unknown)}; choose from {', '.join(METHODS)}", file=sys.stderr)
        return 2
    peers = args.peers if args.peers is not None else ["eevee", "cycles"]
    peers = [] if peers == ["none"] else peers
    opts = Options(
        scenes=args.scenes or list(BUILDERS),
        methods=methods,
        sizes=args.sizes or list(QUICK_SIZES if args.quick else DEFAULT_SIZES),
        resolution=args.resolution or base["resolution"],
        frames=args.frames if args.frames is not None else base["frames"],
        peers=tuple(peers),
        eevee_samples=args.eevee_samples if args.eevee_samples is not None else base["eevee_samples"],
        out=args.out,
        quick=args.quick,
    )
    print(f"Lixel report: {len(opts.scenes)} scene(s) x {len(opts.methods)} method(s) x {len(opts.sizes)} size(s) "
          f"at {opts.resolution[0]}x{opts.resolution[1]}, {opts.frames} frame(s); peers: {', '.join(opts.peers) or 'none'}",
          flush=True)
    result = run(opts, log=lambda m: print(m, flush=True))
    paths = document.write(result, opts.out, progress=lambda m: print(m, flush=True),
                           readme_picture=args.readme_picture)
    print(f"wrote {paths['html']} and {paths['md']} ({result['seconds']:.0f} s)", flush=True)
    return 0


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    os._exit(code)  # Blender 4.2/4.5 may crash or hang at interpreter exit (shared notes §8.5)
