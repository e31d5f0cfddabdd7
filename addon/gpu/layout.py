"""The shading pass's uniform block, written once: the Python definition below
is both what :func:`addon.gpu.pipeline.shade_block` fills and the GLSL
``struct`` the shaders read (:meth:`Struct.glsl`, given to every shading
shader as its typedef source).

std140 without padding questions: every member is a ``vec4``, a ``mat4``, a
struct of those or an array of them, so each member starts on a 16-byte row
and a block is a plain (rows, 4) float32 array. A ``mat4`` is four rows, one
per column (GLSL matrices are column-major).

``tests/blender/test_gpu_layout.py`` reads every row back through the GLSL
member names and compares it with the Python side.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Union

import numpy as np

MAX_MAPS = 8
"""Shadow maps one shading pass can select from (sampler slots 0..7)."""
MAX_POLYGON = 32
"""Vertices of a plane map's region polygon passed to the shader."""


@dataclass(frozen=True)
class Member:
    """One member: ``kind`` is "vec4", "mat4" or a :class:`Struct`; ``count`` > 1 makes it an array."""

    name: str
    kind: Union[str, "Struct"]
    doc: str = ""
    count: int = 1

    @property
    def rows_each(self) -> int:
        if isinstance(self.kind, Struct):
            return self.kind.rows
        return {"vec4": 1, "mat4": 4}[self.kind]

    @property
    def rows(self) -> int:
        return self.rows_each * self.count


@dataclass(frozen=True)
class Struct:
    name: str
    members: tuple[Member, ...]
    doc: str = ""

    @property
    def rows(self) -> int:
        return sum(m.rows for m in self.members)

    def offset(self, name: str) -> int:
        """First row of member ``name``."""
        row = 0
        for m in self.members:
            if m.name == name:
                return row
            row += m.rows
        raise KeyError(f"{self.name} has no member {name!r}")

    def member(self, name: str) -> Member:
        return next(m for m in self.members if m.name == name)

    def structs(self) -> list["Struct"]:
        """This struct and the structs it holds, innermost first (GLSL declaration order)."""
        out: list[Struct] = []
        for m in self.members:
            if isinstance(m.kind, Struct):
                out += [s for s in m.kind.structs() if s not in out]
        return out + [self]

    def glsl(self) -> str:
        """GLSL declarations of this struct and the structs it holds."""
        parts = []
        for s in self.structs():
            lines = [f"/* {s.doc} */"] if s.doc else []
            lines.append(f"struct {s.name} {{")
            for m in s.members:
                kind = m.kind.name if isinstance(m.kind, Struct) else m.kind
                array = f"[{m.count}]" if m.count > 1 else ""
                doc = f"  /* {m.doc} */" if m.doc else ""
                lines.append(f"  {kind} {m.name}{array};{doc}")
            lines.append("};")
            parts.append("\n".join(lines))
        return "\n\n".join(parts) + "\n"

    def block(self) -> "BlockView":
        """A zeroed float64 block of this layout, filled through member names."""
        return BlockView(self, np.zeros((self.rows, 4), dtype=np.float64))


class BlockView:
    """Named access to the rows of a block: ``b.camera[:] = ...``,
    ``b.maps[2].matrix[:] = M.T`` (columns), ``b.maps[0].polygon[:n, :3] = ...``.
    Every access returns a numpy view into ``rows``."""

    def __init__(self, struct: Struct, rows: np.ndarray):
        object.__setattr__(self, "struct", struct)
        object.__setattr__(self, "rows", rows)

    def __getattr__(self, name: str):
        s = self.struct
        try:
            m = s.member(name)
        except StopIteration:
            raise AttributeError(f"{s.name} has no member {name!r}") from None
        start = s.offset(name)
        rows = self.rows[start:start + m.rows]
        if isinstance(m.kind, Struct):
            each = m.kind.rows
            views = [BlockView(m.kind, rows[i * each:(i + 1) * each]) for i in range(m.count)]
            return views if m.count > 1 else views[0]
        if m.kind == "vec4":
            return rows if m.count > 1 else rows[0]
        return rows.reshape(m.count, 4, 4) if m.count > 1 else rows

    def __setattr__(self, name, value):
        raise AttributeError("assign into the views (b.camera[:] = ...), not the attributes")

    def float32(self) -> np.ndarray:
        return self.rows.astype(np.float32)


LIXEL_MAP = Struct("LixelMap", (
    Member("matrix", "mat4", "world -> light clip (relative to the frame's origin)"),
    Member("depth_row", "vec4", "linear z row (Scherzer §4.2), used when info.w = 1"),
    Member("info", "vec4", "(width, height, greater (0/1), linear z (0/1))"),
    Member("range", "vec4", "(min eye depth, max eye depth, has range (0/1), region vertex count)"),
    Member("plane", "vec4", "region plane (normal.xyz, offset)"),
    Member("extra", "vec4", "(region tolerance, blend band: eye depth past range.y the map still holds, 0, 0)"),
    Member("polygon", "vec4", "region polygon vertices (xyz, 1)", MAX_POLYGON),
), doc="One per ShadowMap of the setup, in selection order (addon.warp.types.ShadowSetup).")

LIXEL_SHADE = Struct("LixelShade", (
    Member("camera", "vec4", "(position.xyz, orthographic (0/1))"),
    Member("view_dir", "vec4", "(camera forward.xyz, -1 for a mirrored camera else 1)"),
    Member("eye_row", "vec4", "row 2 of world -> camera (eye depth = -dot(eye_row, [P, 1]))"),
    Member("light_pos", "vec4", "(position.xyz, type: 0 sun, 1 point, 2 spot)"),
    Member("light_dir", "vec4", "(travel direction.xyz, cos of the spot's half angle)"),
    Member("light_color", "vec4", "(colour * energy, albedo)"),
    Member("spot", "vec4", "(Blender's spot blend 0..1, 0, 0, 0)"),
    Member("ambient", "vec4", "(world colour, 0): ambient light, times the albedo"),
    Member("bias", "vec4", "(constant c, slope factor s or normal offset, PCF reach r, mode), receiver texels"),
    Member("inv_view_proj", "mat4", "camera clip -> world (relative to the frame's origin): the camera rays"),
    Member("screen", "vec4", "(2 / width, 2 / height, 0, 0): window position -> NDC"),
    Member("maps", LIXEL_MAP, "the setup's maps", MAX_MAPS),
), doc="The shading pass's uniform block (addon/gpu/layout.py); positions relative to the frame's origin.")
