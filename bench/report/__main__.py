"""``make demo`` = ``python -m bench.report``: the speed-against-error report.

    python -m bench.report                       # every sample scene, every method (about 12 minutes here)
    python -m bench.report --quick               # the short version, every section (about 3 minutes here)
    python -m bench.report --scene chess --methods uniform,lispsm --sizes 1024,4096

Writes OUT/report.html, OUT/report.md, OUT/report.json and OUT/<scene>/*.png
(OUT = out/ by default). The report is built in a temporary folder beside OUT
and moved into place only when it is complete: a bad --scene or --methods is
refused before anything runs (exit status 2), and a run that fails or is
interrupted leaves the last report as it was.
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MANIFEST = ".lixel-report-files"
"""In OUT: the entries the last report wrote (so the next one can replace exactly those)."""


def _scratch_env() -> None:
    # Keep Blender's and Mesa's caches and user resources out of $HOME (before bpy loads).
    scratch = Path(tempfile.gettempdir()) / "lixel-report"
    os.environ.setdefault("XDG_CACHE_HOME", str(scratch / "xdg"))
    os.environ.setdefault("BLENDER_USER_RESOURCES", str(scratch / "blender-user"))
    # One BLAS thread (before numpy loads): Lixel's arrays are small, and idle BLAS threads
    # spinning against llvmpipe's only add noise to the timings.
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def _csv(text: str) -> list[str]:
    return [t.strip() for t in text.split(",") if t.strip()]


def _sizes(text: str) -> list[int]:
    try:
        return [int(x) for x in _csv(text)]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give map sizes as integers, e.g. 1024,2048") from None


def _resolution(text: str) -> tuple[int, int]:
    try:
        w, h = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give the render size as WxH, e.g. 640x360") from None
    return w, h


def parse(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="python -m bench.report", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="small resolution, fewer frames, sizes and repeats")
    ap.add_argument("--scene", "--scenes", dest="scenes", type=_csv, default=None,
                    help="comma-separated scene names or .blend paths (default: all sample scenes)")
    ap.add_argument("--methods", type=_csv, default=None, help="comma-separated warp methods (default: all)")
    ap.add_argument("--sizes", type=_sizes, default=None, help="comma-separated shadow-map sizes in texels per side")
    ap.add_argument("--peers", type=_csv, default=None, help="eevee,cycles (default both; 'none' for neither)")
    ap.add_argument("--eevee-sizes", type=_sizes, default=None,
                    help="map sizes EEVEE is matched to (default: every size; --quick: the largest)")
    ap.add_argument("--resolution", type=_resolution, default=None, help="render size WxH")
    ap.add_argument("--frames", type=int, default=None, help="frames of camera animation for flicker")
    ap.add_argument("--repeats", type=int, default=None, help="timed frames per Lixel point (median, min, max)")
    ap.add_argument("--peer-repeats", type=int, default=None, help="timed renders per peer point")
    ap.add_argument("--eevee-samples", type=int, default=None, help="EEVEE render samples (default 1)")
    ap.add_argument("--no-overlays", action="store_true", help="skip the overlay snapshots")
    ap.add_argument("--out", type=Path, default=ROOT / "out", help="report folder (default: out/)")
    ap.add_argument("--readme-pictures", type=Path, default=None, metavar="DIR",
                    help="also write the README's pictures for the first scene into DIR (docs/images): "
                         "comparison.png, overlay_observer.png, overlay_texels.png")
    return ap.parse_args(argv)


def options(args):
    from sample_blends.scenes import BUILDERS
    from addon.warp import METHODS
    from .run import DEFAULT_SIZES, QUICK_SIZES, Options, full_defaults, quick_defaults
    base = quick_defaults() if args.quick else full_defaults()
    sizes = args.sizes or list(QUICK_SIZES if args.quick else DEFAULT_SIZES)
    peers = args.peers if args.peers is not None else ["eevee", "cycles"]
    peers = [] if peers == ["none"] else peers or [""]   # ("": none given, refused by name)
    from .run import MAX_MAP_SIZE
    fitting = [s for s in sizes if s <= MAX_MAP_SIZE]
    eevee_sizes = args.eevee_sizes if args.eevee_sizes is not None else \
        ([max(fitting)] if args.quick and fitting else None)
    return Options(
        scenes=args.scenes if args.scenes is not None else list(BUILDERS),
        methods=args.methods if args.methods is not None else list(METHODS),
        sizes=sizes,
        resolution=args.resolution or base["resolution"],
        frames=args.frames if args.frames is not None else base["frames"],
        peers=tuple(peers),
        eevee_samples=args.eevee_samples if args.eevee_samples is not None else 1,
        repeats=args.repeats if args.repeats is not None else base["repeats"],
        peer_repeats=args.peer_repeats if args.peer_repeats is not None else base["peer_repeats"],
        eevee_sizes=eevee_sizes,
        overlays=not args.no_overlays,
        out=args.out,
        quick=args.quick,
    )


def last_reports(out: Path) -> set:
    """The entries of ``out`` the last report wrote (its manifest)."""
    return set((out / MANIFEST).read_text().split("\n")) - {""} if (out / MANIFEST).is_file() else set()


def folder_problems(opts, readme_pictures) -> list:
    """Why the report could not be put where the options say, found before anything runs (it was found after the
    run, as a traceback that lost it): ``--out`` or ``--readme-pictures`` naming a file (or a broken link), or
    ``--out`` holding an entry the report would replace (report.*, a scene's folder) that the last report there did
    not write: the user's own, which publishing removed."""
    out = Path(opts.out)
    problems = [f"{option}: {path} is not a folder: name a folder" for option, path in
                (("--out", out), ("--readme-pictures", readme_pictures))
                if path is not None and os.path.lexists(path) and not path.is_dir()]   # a file, a broken link
    if out.is_dir():
        names = {"report.html", "report.md", "report.json"} | {Path(str(name)).stem for name in opts.scenes}
        if theirs := sorted(name for name in names - last_reports(out) if os.path.lexists(out / name)):
            problems.append(f"--out: {out} holds {', '.join(map(repr, theirs))}, which this report would replace and "
                            f"the last report there did not write (its list, {MANIFEST}, does not name them): name "
                            f"another folder, or move them")
    return problems


def publish(partial: Path, out: Path) -> None:
    """Move the finished report from ``partial`` into ``out``: the entries the
    last report wrote (its manifest) are replaced, anything else in ``out`` stays."""
    out.mkdir(parents=True, exist_ok=True)
    old = last_reports(out)
    new = sorted(p.name for p in partial.iterdir())
    for name in old | set(new):
        target = out / name
        if "/" in name or name in ("", ".", ".."):
            continue
        if target.is_dir() and not target.is_symlink():
            shutil.rmtree(target)
        elif target.exists() or target.is_symlink():
            target.unlink()
    for name in new:
        (partial / name).rename(out / name)
    (out / MANIFEST).write_text("\n".join(new) + "\n")
    partial.rmdir()


def main(argv=None) -> int:
    args = parse(argv)
    _scratch_env()
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    from .progress import quiet_blender
    with quiet_blender():
        import bpy  # noqa: F401 - loads Blender before anything uses mathutils
    from . import document
    from .progress import Progress
    from .run import GUESS_S, check, cleanup, plan, run

    opts = options(args)
    problems = check(opts) + folder_problems(opts, args.readme_pictures)
    if problems:
        for p in problems:
            print(f"python -m bench.report: error: {p}", file=sys.stderr)
        print("nothing was run; the last report is unchanged", file=sys.stderr)
        return 2
    out = Path(opts.out).resolve()
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        partial = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=out.parent))
    except OSError as exc:
        print(f"python -m bench.report: error: --out: cannot write in {out.parent}: {exc.strerror}", file=sys.stderr)
        print("nothing was run; the last report is unchanged", file=sys.stderr)
        return 2
    progress = Progress(plan(opts), GUESS_S)
    steps = len(progress.plan)
    progress.log(f"Lixel report: {len(opts.scenes)} scene(s) x {len(opts.methods)} method(s) x {len(opts.sizes)} "
                 f"size(s) at {opts.resolution[0]}x{opts.resolution[1]}, {opts.frames} frame(s), {opts.repeats} "
                 f"timed frames a point; peers: {', '.join(opts.peers) or 'none'}; {steps} steps, "
                 f"~{progress.seconds_left() / 60:.0f} min")
    result = None
    try:
        result = run(opts, progress)
        if not any(m.get("status") == "ok" for scene in result["scenes"] for m in scene.get("methods", ())):
            progress.log("nothing was measured: every scene or method failed (the reasons are above); "
                         "the last report is unchanged")
            return 1
        paths = document.write(result, partial, progress)
        publish(partial, out)
        if args.readme_pictures is not None:
            for path in document.readme_pictures(result, out, args.readme_pictures):
                progress.log(f"wrote {path}")
        failed = [s["name"] for s in result["scenes"] if s.get("status") != "ok"]
        progress.log(f"wrote {out / paths['html'].name} and {out / paths['md'].name} in {progress.elapsed():.0f} s "
                     f"({time.process_time():.0f} s of CPU time)"
                     + (f"; FAILED scenes: {', '.join(failed)}" if failed else ""))
        return 0
    except KeyboardInterrupt:
        progress.log("interrupted; the last report is unchanged")
        return 130
    finally:
        progress.close()
        if partial.exists():
            shutil.rmtree(partial, ignore_errors=True)
        if result is not None:
            cleanup(result)


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)  # Blender 4.2/4.5 may crash or hang at interpreter exit (shared notes §8.5)
