"""Rebuild the sample .blend files from sample_blends/scenes.py.

    .venv-4.2/bin/python sample_blends/build.py        # all scenes, readable by every supported Blender
    .venv/bin/python sample_blends/build.py            # the same with Blender 5.0
    .venv/bin/python sample_blends/build.py forest     # some
    .venv/bin/python sample_blends/build.py --out DIR  # somewhere else

Each file is saved compressed next to this script (``<name>.blend``).
The committed files are built with Blender 4.2: Blender 4.2 cannot open files
saved by 5.0 ("not a blend file"), while 5.0 opens 4.2's. Both versions evaluate
the scenes identically (instance transforms agree to float32 rounding).
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent


def _scratch_env() -> None:
    # Keep Blender's and Mesa's caches and user resources out of $HOME (before bpy loads).
    scratch = Path(tempfile.gettempdir()) / "lixel-build"
    os.environ.setdefault("XDG_CACHE_HOME", str(scratch / "xdg"))
    os.environ.setdefault("BLENDER_USER_RESOURCES", str(scratch / "blender-user"))


def build(names=None, out_dir: Path = HERE, log=print) -> list[Path]:
    """Build the named scenes (default: all) and save them; returns the paths."""
    _scratch_env()
    import bpy

    if str(HERE.parent) not in sys.path:
        sys.path.insert(0, str(HERE.parent))
    from sample_blends import scenes

    names = list(names or scenes.BUILDERS)
    unknown = [n for n in names if n not in scenes.BUILDERS and n != "tiny"]
    if unknown:
        raise SystemExit(f"unknown scene(s) {', '.join(unknown)}; choose from {', '.join(scenes.BUILDERS)}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for name in names:
        builder = scenes.build_tiny if name == "tiny" else scenes.BUILDERS[name]
        builder()
        path = out_dir / f"{name}.blend"
        bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=True, copy=False)
        log(f"built {path} ({path.stat().st_size / 1e6:.2f} MB)")
        paths.append(path)
    return paths


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="*", help="scene names (default: all)")
    ap.add_argument("--out", type=Path, default=HERE, help="output folder (default: sample_blends/)")
    args = ap.parse_args(argv)
    build(args.scenes, args.out)


if __name__ == "__main__":
    main()
