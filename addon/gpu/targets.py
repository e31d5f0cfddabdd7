"""Render targets kept across frames.

A frame of the same size draws into the same textures and framebuffers as
the last one (allocating them costs about 13 ms and 48 MB a frame on
llvmpipe). A :class:`TargetPool` hands out a texture per (name, size, format)
and a framebuffer per set of attachments; asking for a name at a new size
replaces what that name held.

Framebuffers belong to the GPU context that made them (textures and batches
are shared between contexts: the render engine's, the window's, the one a
background script gets), so a pool keeps framebuffers per context. The
context is told by the framebuffer active when a frame asks for one (the
context's own; Blender keeps one Python object per framebuffer, so the
object's identity is the context's).
"""
from __future__ import annotations

import functools

from ..warp.types import WarpError

BYTES_PER_TEXEL = {"DEPTH_COMPONENT32F": 4, "R32F": 4, "RG32F": 8, "RGBA32F": 16, "RGBA16F": 8, "R16F": 2, "RGBA8": 4}
"""GPU memory a texel of each texture format Lixel allocates takes."""
MAP_BYTES_LIMIT = 4 * 2 ** 30
"""The most GPU memory a frame's shadow maps may take: 4 GiB (Blender's Python gpu module tells no device's memory).
The cascade's 8 splits at 4096² take 512 MiB, with 4 MDSM depths 2.5 GiB; at 16384² one map takes 1 GiB and eight
8 GiB, which fails deep in the GPU driver or takes the machine's memory (llvmpipe allocates it on the CPU)."""


def map_bytes(sizes, mdsm: bool = False) -> int:
    """GPU bytes of shadow maps of ``sizes`` ((w, h) each): a 32-bit depth texture each, and with ``mdsm`` (MDSM
    Depths > 1) an RGBA32F key map each (``pipeline.mdsm_pass``)."""
    per_texel = BYTES_PER_TEXEL["DEPTH_COMPONENT32F"] + (BYTES_PER_TEXEL["RGBA32F"] if mdsm else 0)
    return sum(int(w) * int(h) for w, h in sizes) * per_texel


def check_map_memory(setup, mdsm: bool = False, limit: int = MAP_BYTES_LIMIT) -> None:
    """WarpError, before anything is allocated, when ``setup``'s maps would take more than ``limit`` bytes of GPU
    memory (:func:`map_bytes`), naming the settings that size them and what to do: the panel's, and the option a
    script sizes the maps with (``--size`` overrides the file's Map Size)."""
    sizes = [m.size for m in setup.maps]
    need = map_bytes(sizes, mdsm)
    if need <= limit:
        return
    n = len(sizes)
    shapes = sorted({f"{int(w)}x{int(h)}" for w, h in sizes})
    splits = any(str(m.role).startswith("split") for m in setup.maps)
    remedies = ["lower the Map Size"] + (["use fewer Splits or a Shared Texel Budget"] if splits else []) + \
        (["set MDSM Depths to 1"] if mdsm else [])
    raise WarpError(f"{n} shadow map{'s' if n > 1 else ''} of {', '.join(shapes)} texels"
                    f"{' with their MDSM keys' if mdsm else ''} would take {need / 2 ** 30:.1f} GiB of GPU memory, "
                    f"more than Lixel's limit of {limit / 2 ** 30:g} GiB: {', '.join(remedies[:-1])}"
                    f"{' or ' if len(remedies) > 1 else ''}{remedies[-1]} (Lixel panel > Method; in a script, "
                    f"--size sets the Map Size)")


class TargetPool:
    MAX_FRAMEBUFFERS = 64
    """Framebuffers kept (the oldest is dropped beyond this)."""
    KEEP_BYTES = 384 * 2 ** 20
    """Texture memory kept between frames (:meth:`trim`): a 1280x720 frame with
    2048² maps keeps about 90 MB; a 16384² map (1 GiB) is freed after its frame."""

    def __init__(self):
        self._textures: dict = {}      # name -> ((size, format), texture)
        self._framebuffers: dict = {}  # (context, attachment ids) -> (framebuffer, attachments, context)
        self.allocations = 0
        """Textures allocated so far (a warm frame of an unchanged size allocates none)."""

    def texture(self, name: str, size: tuple[int, int], fmt: str):
        """The texture called ``name``, (re)allocated when its size or format changed."""
        import gpu
        size = (int(size[0]), int(size[1]))
        hit = self._textures.get(name)
        if hit is not None and hit[0] == (size, fmt):
            return hit[1]
        if hit is not None:
            self._forget(hit[1])
        tex = gpu.types.GPUTexture(size, format=fmt)
        self._textures[name] = ((size, fmt), tex)
        self.allocations += 1
        return tex

    def framebuffer(self, depth=None, colors: tuple = ()):
        """A framebuffer with these attachments in the current context (made
        once per combination and context)."""
        import gpu
        context = gpu.state.active_framebuffer_get()
        key = (id(context), id(depth), tuple(id(c) for c in colors))
        hit = self._framebuffers.get(key)
        if hit is not None:
            return hit[0]
        if len(self._framebuffers) >= self.MAX_FRAMEBUFFERS:
            self._framebuffers.pop(next(iter(self._framebuffers)))  # the oldest
        fb = gpu.types.GPUFrameBuffer(depth_slot=depth, color_slots=tuple(colors))
        # The entry holds what its key's ids name, so no id is reused while it exists.
        self._framebuffers[key] = (fb, depth, tuple(colors), context)
        return fb

    def _forget(self, tex) -> None:
        for key in [k for k, (_, d, cs, _) in self._framebuffers.items() if d is tex or any(c is tex for c in cs)]:
            del self._framebuffers[key]

    def clear(self) -> None:
        self._textures.clear()
        self._framebuffers.clear()

    def trim(self, keep_bytes: int | None = None) -> None:
        """Free the largest textures until the pool holds at most ``keep_bytes``
        (default :attr:`KEEP_BYTES`); called at the end of every frame."""
        limit = self.KEEP_BYTES if keep_bytes is None else keep_bytes
        while self.bytes > limit and self._textures:
            name = max(self._textures, key=lambda n: self._size_of(*self._textures[n][0]))
            self._forget(self._textures.pop(name)[1])

    @staticmethod
    def _size_of(size, fmt) -> int:
        return size[0] * size[1] * BYTES_PER_TEXEL.get(fmt, 16)

    @property
    def bytes(self) -> int:
        """GPU memory held by the pool's textures."""
        return sum(self._size_of(*key) for key, _ in self._textures.values())


@functools.cache
def shared_targets() -> TargetPool:
    """The process-wide pool (the render engine's context; background scripts)."""
    return TargetPool()
