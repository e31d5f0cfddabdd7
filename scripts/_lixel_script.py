"""What the background scripts share: argument parsing in both ways of running,
loading the .blend, registering Lixel (so the file's Lixel settings apply) and
unregistering it before exit (Blender 4.2 crashes at exit otherwise).

Two ways to run every script::

    blender -b file.blend --python scripts/X.py -- [args]
    python scripts/X.py file.blend [args]          # with the bpy module

Arguments come after ``--`` when it is present, else after the script name.
Bad arguments print the usage and exit with status 2; a scene Lixel cannot
handle (no camera, no light, ...) prints ``lixel: error: ...`` and exits 1,
as does anything unexpected (one line; ``LIXEL_DEBUG=1`` shows the traceback).
Ctrl-C is one line too (exit status 130).
"""
from __future__ import annotations

import argparse
import contextlib
import copy
import importlib
import importlib.util
import os
import sys
import tempfile
import traceback
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "lixel"
"""The package name this checkout is imported under when Blender has not
already enabled Lixel as an extension."""


FRAMES = (-1048574, 1048574)
"""Blender's frames (MINAFRAME..MAXFRAME, 4.2 and 5.0): ``Scene.frame_set`` moves a frame beyond them to the
nearest end without a word."""


def check_frames(parser: argparse.ArgumentParser, option: str, text, *frames: int) -> None:
    """Usage error (exit 2) when a frame of ``option`` lies outside Blender's :data:`FRAMES`."""
    lo, hi = FRAMES
    if any(not lo <= f <= hi for f in frames):
        parser.error(f"{option} {text}: Blender's frames run from {lo} to {hi}")


def names_option(parser: argparse.ArgumentParser, option: str, text: str, allowed) -> list:
    """The comma-separated names of ``option`` (``--methods``, ``--views``); usage error (exit 2) for a name not in
    ``allowed``, for none ("", an empty shell variable) and for one given twice."""
    names = [n.strip() for n in text.split(",") if n.strip()]
    bad = [n for n in names if n not in allowed]
    if bad or not names:
        parser.error(f"{option}: unknown {', '.join(bad) or '(none given)'}; choose from {', '.join(allowed)}")
    if twice := sorted({n for n in names if names.count(n) > 1}):
        parser.error(f"{option}: {', '.join(twice)} given twice: name each once")
    return names


class ScriptError(Exception):
    """A problem with the scene, reported as ``lixel: error: ...`` (exit status 1)."""


def script_args(argv=None) -> tuple[list, bool]:
    """(arguments, inside_blender): the arguments after ``--`` if present (Blender's
    convention), else everything after the script."""
    argv = list(sys.argv if argv is None else argv)
    if "--" in argv:
        return argv[argv.index("--") + 1:], True
    return argv[1:], False


def base_parser(prog: str, description: str) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=prog, description=description,
        epilog=f"Run as: blender -b FILE.blend --python scripts/{prog} -- [options]  or  "
               f"python scripts/{prog} FILE.blend [options]")
    p.add_argument("blend", nargs="?", help="the .blend file (optional inside Blender, where -b loaded it)")
    p.add_argument("--scene", help="scene name (default: the file's active scene)")
    p.add_argument("--camera", help="camera object (default: the scene camera)")
    p.add_argument("--light", help="light object (default: the scene's Lixel light, else the active light, "
                                   "else the first sun)")
    p.add_argument("--size", type=int, help="shadow map size in texels per side (default: the scene's setting)")
    return p


BLENDER_PYTHON_OPTIONS = ("--python", "-P")
"""How Blender's command line names the script it runs: a command line holding one is Blender's own."""


def parse(parser: argparse.ArgumentParser, argv=None):
    """Parse and check the arguments; errors print usage and exit 2."""
    args_list, inside = script_args(argv)
    if not inside and any(a in BLENDER_PYTHON_OPTIONS for a in args_list):
        parser.error("Blender passes a script only the arguments after '--': blender -b FILE.blend --python "
                     f"scripts/{parser.prog} -- [options]")
    args = parser.parse_args(args_list)
    if args.blend is None and not inside:
        parser.error("the .blend file is required (python scripts/X.py FILE.blend ...)")
    if args.blend is not None:
        if not args.blend.endswith(".blend"):
            parser.error(f"{args.blend!r} is not a .blend file")
        if not os.path.isfile(args.blend):
            parser.error(f"no such .blend file: {args.blend}")
    if args.size is not None:
        limits = importlib.import_module(f"{_import_checkout().__name__}.addon.settings")
        if not limits.MIN_MAP_SIZE <= args.size <= limits.MAX_MAP_SIZE:
            parser.error(f"--size {args.size} is out of range: use {limits.MIN_MAP_SIZE}..{limits.MAX_MAP_SIZE} "
                         f"texels per side")
    return args


@contextlib.contextmanager
def data_stdout(reserve: bool = True):
    """Standard output kept for the script's data (``--output -``): while the
    block runs, everything else written to it (Blender's "Read blend: ..." line,
    which C code prints to file descriptor 1 when a file is opened, and any
    Python print) goes to standard error instead; yields the text stream that
    reaches the real standard output. ``reserve=False``: plain ``sys.stdout``.

    Inside the Blender binary, lines Blender prints *before* the script runs
    (opening the file given on its command line) cannot be taken back: run it
    as ``blender -b -q file.blend --python ...`` (``-q``: no status lines)."""
    if not reserve:
        yield sys.stdout
        return
    sys.stdout.flush()
    saved = os.dup(1)
    os.dup2(2, 1)
    data = os.fdopen(os.dup(saved), "w", encoding="utf-8")
    try:
        yield data
    finally:
        data.flush()
        data.close()
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)


OUTPUT_OPTIONS = ("output", "json", "shadow_output", "map_output", "output_dir")
"""The scripts' options that name files or folders to write."""


def writable_folder(folder: str) -> None:
    """ScriptError naming ``--output-dir``, why and what to do where it cannot be written (or made), said before any
    work: compare_methods said so only after the whole comparison had been computed and printed. Nothing is made
    here: a nameless file is tried in the folder, or in the nearest folder above that exists, where it would be made
    (as root, permissions alone do not tell)."""
    nearest = os.path.abspath(folder)
    while not os.path.exists(nearest):
        nearest = os.path.dirname(nearest)
    if not os.path.isdir(nearest):
        why = f"{nearest} is a file, not a folder"
    else:
        try:
            with tempfile.TemporaryFile(dir=nearest):
                pass
            return
        except OSError as exc:
            why = f"{exc.strerror or exc} ({nearest})"
    raise ScriptError(f"--output-dir {folder} cannot be written: {why}: name a folder you can write to (one that is "
                      f"missing is made)")


class Session:
    """Opens the file, registers Lixel if Blender has not, and always unregisters."""

    def __init__(self, args):
        self.args = args
        self.package = None
        self.registered = False
        self.shown: list = []     # (setter, value before) of what show_as_rendered changed, undone on exit
        self.warned = False       # Is Viewport said (once a session)

    def __enter__(self):
        import bpy
        self.bpy = bpy
        if hasattr(bpy.types.Scene, "lixel"):  # Lixel already enabled in this Blender: use its registration
            self.package = _import_checkout()
        else:
            self.package = _import_checkout()
            self.package.register()
            self.registered = True
        try:
            if self.args.blend is not None:
                try:
                    bpy.ops.wm.open_mainfile(filepath=os.path.abspath(self.args.blend))
                except RuntimeError as exc:
                    raise ScriptError(f"cannot open {self.args.blend}: {str(exc).strip()} (a file saved by a newer "
                                      f"Blender cannot be read by an older one)") from None
            elif not bpy.data.filepath:
                raise ScriptError("no .blend file is loaded: pass one (blender -b FILE.blend --python ...)")
            for name in OUTPUT_OPTIONS:   # "//out.png": beside the .blend file, as in Blender (the OS reads "/out.png")
                path = getattr(self.args, name, None)
                if isinstance(path, str) and path.startswith("//"):
                    setattr(self.args, name, bpy.path.abspath(path))
                    path = getattr(self.args, name)
                if isinstance(path, str) and os.path.exists(path) and os.path.samefile(path, bpy.data.filepath):
                    raise ScriptError(f"--{name.replace('_', '-')} {path} is the .blend file being read: writing "
                                      f"there would destroy it; choose another name")
            folder = getattr(self.args, "output_dir", None)   # said after the whole comparison: 'File exists'
            if isinstance(folder, str) and os.path.exists(folder) and not os.path.isdir(folder):
                raise ScriptError(f"--output-dir {folder} is a file, not a folder: name a folder (one that is missing "
                                  f"is made)")
            if isinstance(folder, str):
                writable_folder(folder)
            named: dict = {}   # one file for two outputs: the second overwrote the first without a word
            for name in OUTPUT_OPTIONS:
                path = getattr(self.args, name, None)
                if isinstance(path, str) and path != "-":
                    other = named.setdefault(os.path.realpath(path), name)
                    if other != name:
                        raise ScriptError(f"--{other.replace('_', '-')} and --{name.replace('_', '-')} both name "
                                          f"{path}: the second would overwrite the first; give each its own file")
        except BaseException:
            self.__exit__(None, None, None)
            raise
        return self

    def __exit__(self, *exc):
        for undo, value in reversed(self.shown):
            with contextlib.suppress(ReferenceError, RuntimeError, AttributeError):
                undo(value)
        self.shown.clear()
        if self.registered:
            self.package.unregister()
            self.registered = False
        return False

    def module(self, name: str):
        return importlib.import_module(f"{self.package.__name__}.{name}")

    def scene(self):
        bpy = self.bpy
        if self.args.scene is not None:    # ("": no scene of that name, as for --camera "", not the active one)
            sc = bpy.data.scenes.get(self.args.scene)
            if sc is None:
                raise ScriptError(f"there is no scene named '{self.args.scene}' "
                                  f"(scenes: {', '.join(s.name for s in bpy.data.scenes)})")
            if bpy.context.window is not None:
                bpy.context.window.scene = sc
            return sc
        return bpy.context.scene

    def objects(self, scene):
        """(camera, light) objects from --camera/--light, or None for the scene's choice."""
        bpy = self.bpy
        out = []
        for opt, kind in ((self.args.camera, "CAMERA"), (self.args.light, "LIGHT")):
            if opt is None:
                out.append(None)
                continue
            ob = bpy.data.objects.get(opt)
            if ob is None:
                raise ScriptError(f"there is no object named '{opt}'")
            if ob.type != kind:
                raise ScriptError(f"object '{opt}' is a {ob.type.lower()}, not a {kind.lower()}")
            out.append(ob)
        return tuple(out)

    def settings(self, scene, method=None):
        """The scene's LixelSettings with --size and ``method`` applied."""
        from dataclasses import replace
        live = self.module("addon.ui.live")
        settings = live.scene_settings(scene)
        if method is not None:
            settings = replace(settings, method=method)
        if self.args.size is not None:
            settings = replace(settings, warp=replace(settings.warp, shadow_map_size=(self.args.size, self.args.size)))
        return settings

    def show_as_rendered(self, scene) -> None:
        """Make the depsgraph the scripts read (the 3D view's: a script has no other) hold what the scene's renders
        hold: every object and collection visible in the viewport exactly where it renders (Restrict Render,
        ``hide_render``; an object hidden in the viewport, by its eye or its monitor, still renders). Without this
        ``render_method.py`` drew a cube hidden from renders, which F12 leaves out, and left out one hidden in the
        viewport, which F12 draws. Modifiers, curves, metaballs, particles and Simplify evaluate with their render
        settings too (:func:`render_evaluation`). Undone when the session ends: nothing of the file changes.
        Made again on each call (each frame of ``export_animation.py``): a render visibility animated over the frames
        is the frame's, where the first frame's held for all (frame 3's matrices were those of a scene still showing
        an object keyframed out of renders there)."""
        bpy = self.bpy
        view_layer = self.bpy.context.view_layer
        change = self.change

        def layers(lc):
            yield lc
            for child in lc.children:
                yield from layers(child)
        for coll in bpy.data.collections:
            with contextlib.suppress(AttributeError):   # a linked (read-only) datablock keeps its viewport flag
                change(coll, "hide_viewport", coll.hide_render)
        for lc in layers(view_layer.layer_collection):
            change(lc, "hide_viewport", False)
        for ob in bpy.data.objects:
            with contextlib.suppress(AttributeError):
                change(ob, "hide_viewport", ob.hide_render)
            with contextlib.suppress(RuntimeError):   # not in this view layer
                if ob.hide_get(view_layer=view_layer):
                    ob.hide_set(False, view_layer=view_layer)
                    self.shown.append((lambda v, o=ob: o.hide_set(v, view_layer=view_layer), True))
        for owner, attr, value in render_evaluation(bpy, scene):
            with contextlib.suppress(AttributeError, TypeError):   # linked (read-only) data keeps its viewport value
                change(owner, attr, value)

    def change(self, owner, attr, value) -> None:
        """Set ``owner.attr`` to ``value`` for the session (undone when it ends)."""
        old = getattr(owner, attr)
        if old != value:
            setattr(owner, attr, value)
            self.shown.append((lambda v, o=owner, a=attr: setattr(o, a, v), old))

    def state(self, scene, settings, empty_ok: bool = False):
        """The live state for the scene (camera/light from the arguments), as a copy of its own: Lixel's live
        update (``depsgraph_update_post``, which a render's GPU start sets off, and ``frame_change_post``)
        recomputes the scene's stored state with the scene's own settings, camera and light. ScriptError on
        failure. A ``--camera`` is the scene's camera for the session, as F12 renders through it: Blender evaluates
        the scene camera wherever it lives (an excluded collection, another scene), where the script read the
        matrix the file last stored (never evaluated: the world origin; "the camera sees no shadow receiver"). A
        ``--light`` must be one the scene shows, as the panel's Lixel light must (``describe.pick_light``): Cycles
        lights nothing with another scene's light, which the script rendered with. A view layer with Surfaces off
        is refused: the script drew its surfaces where F12 shows the world alone (4066 of 5184 pixels differed).
        ``empty_ok``: a frame with nothing to shadow (the camera looks at the sky) is returned, its ``empty_body``
        saying why, where F12 renders it unshadowed (by default it is a ScriptError)."""
        live = self.module("addon.ui.live")
        camera, light = self.objects(scene)
        layer = self.bpy.context.view_layer
        if not getattr(layer, "use_solid", True):   # F12 and Cycles draw no surface: the world alone, no shadow
            raise ScriptError(f"view layer '{layer.name}' has Surfaces off (View Layer properties > Filter), so as in "
                              f"Cycles its renders show only the world background: switch Surfaces on")
        if camera is not None:
            self.change(scene, "camera", camera)
        self.show_as_rendered(scene)
        if not self.warned and (names := [n for n in asks_is_viewport(self.bpy) if n in scene.objects]):
            self.warned = True
            print(f"lixel: warning: object '{names[0]}'{f' and {len(names) - 1} more' if len(names) > 1 else ''} "
                  f"{'has' if len(names) == 1 else 'have'} Geometry Nodes that ask Is Viewport: a script evaluates "
                  f"them as the 3D view does, F12 and Cycles as renders; render with F12 (the Lixel engine) for the "
                  f"render's answer", file=sys.stderr)
        depsgraph = self.bpy.context.evaluated_depsgraph_get()
        st = live.update(scene, depsgraph, settings=settings, camera=camera, light_obj=light, changed=None,
                         active=self.bpy.context.view_layer.objects.active)
        if st.error and not (empty_ok and st.empty_body):
            raise ScriptError(st.error)
        return copy.copy(st)


def render_evaluation(bpy, scene):
    """(owner, viewport attribute, render value) for each viewport setting that evaluates otherwise in a render:
    an instancer shown (Object properties > Instancing > Show Instancer: a particle emitter, a mesh instancing on
    its faces), a modifier's eye (Realtime) against its camera (Render), Subdivision Surface and Multiresolution
    levels, Simplify's subdivision and child particle limits, curves' and metaballs' resolution, particles' display
    amount, children and display (a system instancing objects shows none in the viewport as Dot or None).
    F12 and Cycles evaluate the render values: without these a Subdivision Surface of Levels Viewport 0 and Render 2
    cast a sharp cube's shadow in ``render_method.py`` and a round one in F12 (7.8% of a 96x54 picture differed), and
    an emitter hidden from renders drew its ground (71%). Geometry Nodes' Is Viewport cannot be changed so and still
    answers True (:func:`asks_is_viewport`)."""
    render = scene.render
    yield render, "simplify_subdivision", render.simplify_subdivision_render
    yield render, "simplify_child_particles", render.simplify_child_particles_render
    for ob in bpy.data.objects:
        yield ob, "show_instancer_for_viewport", ob.show_instancer_for_render   # an instancer's own surface
        for md in ob.modifiers:
            yield md, "show_viewport", md.show_render
            if md.type in ("SUBSURF", "MULTIRES"):
                yield md, "levels", md.render_levels
    for curve in bpy.data.curves:
        for axis in ("u", "v"):
            if getattr(curve, f"render_resolution_{axis}"):   # 0: the viewport's resolution
                yield curve, f"resolution_{axis}", getattr(curve, f"render_resolution_{axis}")
    for mball in bpy.data.metaballs:
        yield mball, "resolution", mball.render_resolution
    for part in bpy.data.particles:
        yield part, "display_percentage", 100
        yield part, "child_percent", part.rendered_child_count
        yield part, "display_method", "RENDER"   # Dot/None in the viewport: no instanced objects there


def asks_is_viewport(bpy) -> list:
    """Names of the objects whose Geometry Nodes (a modifier shown in renders) hold an Is Viewport node, in their
    group or a group inside it: a script evaluates them as the 3D view does (True), F12 and Cycles as renders."""
    def asks(tree, seen):
        if tree is None or tree in seen:
            return False
        seen.add(tree)
        return any(node.bl_idname == "GeometryNodeIsViewport" or asks(getattr(node, "node_tree", None), seen)
                   for node in tree.nodes)
    return sorted(ob.name for ob in bpy.data.objects
                  if any(md.type == "NODES" and md.show_render and asks(md.node_group, set()) for md in ob.modifiers))


def _import_checkout():
    """This checkout as the package ``lixel`` (its modules use relative imports)."""
    if PACKAGE in sys.modules:
        return sys.modules[PACKAGE]
    spec = importlib.util.spec_from_file_location(PACKAGE, ROOT / "__init__.py",
                                                  submodule_search_locations=[str(ROOT)])
    mod = importlib.util.module_from_spec(spec)
    sys.modules[PACKAGE] = mod
    spec.loader.exec_module(mod)
    return mod


def _user_message(exc: BaseException, doing: str) -> str:
    """The guard's message (addon/guard.py): a WarpError's text, or one line for
    a bug with its traceback in the debug log (LIXEL_DEBUG=1 shows it)."""
    try:
        guard = importlib.import_module(f"{_import_checkout().__name__}.addon.guard")
    except Exception:  # noqa: BLE001 - the checkout itself does not import
        if os.environ.get("LIXEL_DEBUG"):
            traceback.print_exception(exc, file=sys.stderr)
        return f"unexpected error while {doing} ({type(exc).__name__}: {exc})"
    return guard.user_message(exc, doing)


def run(main) -> None:
    """Run ``main()``; map ScriptError and the warp core's errors to exit status 1.

    The process ends with ``os._exit`` after flushing: the Blender 4.2 bpy module
    segfaults at interpreter exit once a class with Python property callbacks
    (``update=``, ``poll=``) has been registered, even after it was unregistered
    (measured; 5.0 exits cleanly). Everything is unregistered and every file
    closed before this point.
    """
    try:
        code = main()
    except SystemExit as exc:  # argparse errors (status 2) and explicit exits
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        if exc.code is not None and not isinstance(exc.code, int):
            print(exc.code, file=sys.stderr)
    except ScriptError as exc:
        print(f"lixel: error: {exc}", file=sys.stderr)
        code = 1
    except BrokenPipeError:  # ``--output - | head``: the reader stopped early and has what it wanted
        code = 1
    except KeyboardInterrupt:  # Ctrl-C: a line, not a traceback (every output is written whole or not at all)
        print("lixel: interrupted: the outputs written so far are whole; the one in progress was not written (a "
              "file already there under its name is kept)", file=sys.stderr)
        code = 130
    except OSError as exc:  # an output the script cannot write: the path (or standard output) and why, not a bug
        where = f"'{exc.filename}'" if exc.filename is not None else "the output"
        print(f"lixel: error: cannot write {where}: {exc.strerror or exc}", file=sys.stderr)
        code = 1
    except Exception as exc:  # noqa: BLE001 - the script's guard: WarpError's message, or one line for a bug
        print(f"lixel: error: {_user_message(exc, f'running {Path(main.__code__.co_filename).name}')}",
              file=sys.stderr)
        code = 1
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except OSError:     # a closed pipe or a full disk, already said
            pass
    os._exit(code or 0)
