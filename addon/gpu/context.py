"""A GPU context for the ``gpu`` module, also in background mode (``blender -b``,
the bpy module).

Shared notes §1: the PyPI bpy module has no ``gpu.init()``; the GPU is brought
up by rendering once with a Python ``RenderEngine`` whose
``bl_use_gpu_context = True``. :func:`ensure_gpu_context` does that in a
throw-away scene (new scene + camera, 4x4 pixels) that it removes afterwards:
the user's scenes, objects and settings are not touched. After that render the
``gpu`` module stays usable for the rest of the process.

Inside ``RenderEngine.render`` of an engine with ``bl_use_gpu_context`` the
context is already active and this is a no-op.
"""
from __future__ import annotations

import contextlib
import logging
import os
import re
import sys
import tempfile
from typing import Callable, Iterator, Optional, TextIO

from ..warp.types import WarpError

log = logging.getLogger(__name__)

_BOOT_ENGINE = "LIXEL_GPU_BOOTSTRAP"


class GPUUnavailableError(WarpError):
    """No GPU context can be had; the message says why and what to try."""


def gpu_available() -> bool:
    """Whether gpu calls work right now (a context exists)."""
    import gpu
    try:
        gpu.platform.backend_type_get()
        return True
    except SystemError:
        return False


EGL_NOISE = re.compile(r"^EGL Error \(0x3009\): EGL_BAD_MATCH")
"""Mesa prints this three times when the context starts in background mode; it is harmless (shared notes §1)."""


@contextlib.contextmanager
def filtered_c_output(is_noise: Callable[[str], bool], out: Optional[TextIO] = None) -> Iterator[None]:
    """File descriptors 1 and 2 (Blender's and Mesa's C output, below Python's
    ``sys.stdout``) into a temporary file for the block, then every line for
    which ``is_noise`` is false on to ``out`` (default: stderr)."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = {fd: os.dup(fd) for fd in (1, 2)}
    with tempfile.TemporaryFile() as sink:
        try:
            for fd in saved:
                os.dup2(sink.fileno(), fd)
            yield
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            for fd, keep in saved.items():
                os.dup2(keep, fd)
                os.close(keep)
            sink.seek(0)
            kept = [ln for ln in sink.read().decode("utf-8", "replace").splitlines() if not is_noise(ln)]
            if kept:
                out = out or sys.stderr
                out.write("\n".join(kept) + "\n")
                out.flush()


def ensure_gpu_context() -> None:
    """Make the ``gpu`` module usable, or raise :class:`GPUUnavailableError`."""
    import bpy
    import gpu

    if gpu_available():
        return
    init = getattr(gpu, "init", None)
    if init is not None:  # Blender newer than 5.0.1
        try:
            init()
        except Exception as exc:  # noqa: BLE001 - reported to the user below
            log.debug("gpu.init() failed: %s", exc)
        if gpu_available():
            return

    class _Bootstrap(bpy.types.RenderEngine):
        bl_idname = _BOOT_ENGINE
        bl_label = "Lixel GPU bootstrap"
        bl_use_gpu_context = True

        def render(self, depsgraph):
            r = self.begin_result(0, 0, 4, 4)
            self.end_result(r)

    bpy.utils.register_class(_Bootstrap)
    scene = cam_data = cam = None
    try:
        scene = bpy.data.scenes.new("Lixel GPU bootstrap")
        cam_data = bpy.data.cameras.new("Lixel GPU bootstrap")
        cam = bpy.data.objects.new("Lixel GPU bootstrap", cam_data)
        scene.collection.objects.link(cam)
        scene.camera = cam
        scene.render.engine = _BOOT_ENGINE
        scene.render.resolution_x = scene.render.resolution_y = 4
        scene.render.resolution_percentage = 100
        with filtered_c_output(EGL_NOISE.match):
            bpy.ops.render.render(scene=scene.name)
    except Exception as exc:  # noqa: BLE001
        raise GPUUnavailableError(f"Lixel could not start the GPU ({exc}): run Blender with a working OpenGL "
                                  f"driver (Mesa llvmpipe works without a graphics card)") from None
    finally:
        if cam is not None:
            bpy.data.objects.remove(cam)
        if cam_data is not None:
            bpy.data.cameras.remove(cam_data)
        if scene is not None:
            bpy.data.scenes.remove(scene)
        bpy.utils.unregister_class(_Bootstrap)
    if not gpu_available():
        raise GPUUnavailableError("Lixel could not get a GPU context: run Blender with a working OpenGL driver "
                                  "(Mesa llvmpipe works without a graphics card)")
