"""numpy's OpenBLAS kept to one thread while a frame is made.

A frame's numpy work is on 4x4 matrices and a few thousand boxes, far below
what BLAS threads speed up, yet one small LAPACK call (``np.linalg.inv`` of a
4x4 matrix, as the depth and shading passes make per map) wakes OpenBLAS's
worker threads, which then busy-wait for more work: measured here, 64-80 ms
of CPU time in the 200 ms after one ``inv`` (numpy 1.26, its bundled OpenBLAS
0.3.23, 2 cores). On a software rasteriser (Mesa llvmpipe) those cores are the
GPU: the spinning workers take their time from the frame's rasterisation.

:func:`one_blas_thread` sets the loaded OpenBLAS to one thread for the block
and gives back the count it had (so the rest of Blender keeps its BLAS
threads). F12 (``render_shadows``, the engine's frame), the sidebar's live
update and the viewport's picture-in-picture hold it. It finds OpenBLAS among
the libraries the process has loaded (Linux) or beside numpy; where there is
none (numpy on Accelerate or MKL, Blender's own builds without it) it does
nothing.
"""
from __future__ import annotations

import ctypes
import functools
import glob
import logging
import os
from contextlib import contextmanager

log = logging.getLogger(__name__)

_SUFFIXES = ("", "64_", "_64_")
"""Symbol suffixes of OpenBLAS's 32- and 64-bit integer builds (numpy's wheels use 64_)."""
_PREFIXES = ("openblas", "scipy_openblas")


def _loaded_paths() -> list:
    """Paths of OpenBLAS libraries loaded in this process (Linux), else those bundled beside numpy."""
    paths = []
    try:
        with open("/proc/self/maps", encoding="utf-8", errors="replace") as maps:
            paths = [line.split(None, 5)[-1].strip() for line in maps if "openblas" in line.lower()]
    except OSError:
        pass
    if not paths:
        import numpy
        here = os.path.dirname(numpy.__file__)
        for folder in ("../numpy.libs", ".libs", ".dylibs"):
            paths += glob.glob(os.path.join(here, folder, "*openblas*"))
    return list(dict.fromkeys(p for p in paths if os.path.isfile(p)))


def _control(lib):
    """(get_num_threads, set_num_threads) of one OpenBLAS library, or None."""
    for prefix in _PREFIXES:
        for suffix in _SUFFIXES:
            get = getattr(lib, f"{prefix}_get_num_threads{suffix}", None)
            put = getattr(lib, f"{prefix}_set_num_threads{suffix}", None)
            if get is not None and put is not None:
                get.restype, put.argtypes = ctypes.c_int, (ctypes.c_int,)
                return get, put
    return None


@functools.cache
def _thread_controls() -> tuple:
    """The thread controls of every OpenBLAS found (see :func:`_loaded_paths`)."""
    controls = []
    for path in _loaded_paths():
        try:
            control = _control(ctypes.CDLL(path))
        except OSError:
            continue
        if control is not None:
            controls.append(control)
    log.debug("Lixel: %d OpenBLAS thread control(s) found", len(controls))
    return tuple(controls)


def openblas_threads() -> list:
    """The thread count of each OpenBLAS found (empty where there is none)."""
    return [get() for get, _ in _thread_controls()]


@contextmanager
def one_blas_thread():
    """OpenBLAS at one thread inside the block, its own count again after it."""
    controls = _thread_controls()
    before = [get() for get, _ in controls]
    for _, put in controls:
        put(1)
    try:
        yield
    finally:
        for (_, put), n in zip(controls, before):
            put(n)
