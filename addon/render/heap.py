"""A frame's render-result buffers reused by the next frame, not mapped afresh (Linux, glibc).

Every F12 Blender allocates the render result's passes (``begin_result``) and
the result they are merged into (``end_result``): at 1280x720, Combined and
Shadow are ~18 MB of float pixels, allocated and freed once per frame.
glibc's ``malloc`` serves blocks above its mmap threshold with fresh mappings
and gives the free top of its heap back to the kernel above its trim
threshold (by default the mmap threshold follows the largest block freed, up
to 32 MiB, and the trim threshold is twice it), so every frame's buffers are
new pages that the kernel must zero and map on first touch. Measured on a warm
F12 at 1280x720 (docs/performance.md): ~9,000 minor page faults, 5.7 ms of
CPU time in copying the Combined pass and 8.2 ms in ``end_result``, against
0.8 and 1.7 ms with the thresholds below.

:func:`keep_frame_buffers` fixes the thresholds at glibc's own ceiling for the
mmap threshold and four times that for the trim threshold (so at most
``TRIM_THRESHOLD`` of freed memory stays with the process), once per process,
where the C library has ``mallopt`` (glibc); elsewhere it does nothing.
"""
from __future__ import annotations

import ctypes
import functools
import logging

log = logging.getLogger(__name__)

M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
"""``mallopt`` parameters (glibc's malloc.h)."""
MMAP_THRESHOLD = 32 << 20
"""Blocks up to this size come from the heap (glibc's DEFAULT_MMAP_THRESHOLD_MAX on 64-bit)."""
TRIM_THRESHOLD = 128 << 20
"""Freed memory at the top of the heap kept for later allocations, at most."""


@functools.cache
def keep_frame_buffers() -> bool:
    """Set glibc's mmap and trim thresholds (see the module docstring); whether they were set."""
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError, TypeError):
        return False  # not glibc (macOS, Windows, musl): its allocator keeps its own policy
    done = bool(mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD))
    log.debug("Lixel: glibc mmap/trim thresholds %s", "set" if done else "refused")
    return done
