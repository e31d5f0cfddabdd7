"""The shading pass's uniform block is written once (addon/gpu/layout.py):
what Python packs is what GLSL reads through the member names."""
import importlib

import numpy as np
import pytest


@pytest.fixture(scope="module")
def gpu_mods(lixel):
    imp = lambda name: importlib.import_module(f"{lixel.__name__}.{name}")  # noqa: E731
    imp("addon.gpu.context").ensure_gpu_context()
    return imp("addon.gpu.layout"), imp("addon.gpu.shaders"), imp("addon.gpu.compose")


def _reader(struct, path: str, depth: int = 0) -> list[str]:
    """GLSL statements returning row ``r{depth}`` of ``struct`` read through its
    member names (``path`` is the struct's own expression)."""
    r = f"r{depth}"
    lines, start = [], 0
    for m in struct.members:
        end = start + m.rows
        name = f"{path}.{m.name}"
        lines.append(f"if ({r} < {end}) {{")
        if isinstance(m.kind, type(struct)):
            inner = f"r{depth + 1}"
            lines.append(f"  int i{depth} = ({r} - {start}) / {m.kind.rows};")
            lines.append(f"  int {inner} = ({r} - {start}) % {m.kind.rows};")
            element = f"{name}[i{depth}]" if m.count > 1 else name
            lines += ["  " + line for line in _reader(m.kind, element, depth + 1)]
        elif m.kind == "mat4":
            lines.append(f"  int c = {r} - {start};")
            lines.append(f"  return {name}[c / 4][c % 4];" if m.count > 1 else f"  return {name}[c];")
        else:
            lines.append(f"  return {name}[{r} - {start}];" if m.count > 1 else f"  return {name};")
        lines.append("}")
        start = end
    return lines


def test_every_row_of_the_block_reads_back_through_its_glsl_name(gpu_mods):
    import gpu
    layout, shaders, compose = gpu_mods
    block = layout.LIXEL_SHADE
    rows = block.rows
    assert rows == 14 + layout.MAX_MAPS * (4 + 5 + layout.MAX_POLYGON)
    values = np.arange(rows * 4, dtype=np.float32).reshape(rows, 4) + 0.25

    info = gpu.types.GPUShaderCreateInfo()
    info.vertex_in(0, "VEC3", "pos")
    info.typedef_source(block.glsl())
    info.uniform_buf(0, block.name, "lixel")
    info.fragment_out(0, "VEC4", "out_row")
    info.vertex_source(shaders.source("fullscreen_vert.glsl"))
    body = "\n  ".join(_reader(block, "lixel"))
    info.fragment_source(f"vec4 lixel_row(int r0)\n{{\n  {body}\n  return vec4(-1.0);\n}}\n\n"
                         "void main()\n{\n  out_row = lixel_row(int(gl_FragCoord.x));\n}\n")
    shader = gpu.shader.create_from_info(info)
    tex = gpu.types.GPUTexture((rows, 1), format="RGBA32F")
    fb = gpu.types.GPUFrameBuffer(color_slots=(tex,))
    ubo = gpu.types.GPUUniformBuf(values.tobytes())
    with fb.bind():
        gpu.state.viewport_set(0, 0, rows, 1)
        shader.bind()
        shader.uniform_block("lixel", ubo)
        compose.fullscreen_batch().draw(shader)
    got = compose.read_color(fb, 0, (rows, 1))[0]
    np.testing.assert_array_equal(got, values)


def test_block_view_names_the_rows_the_shader_reads(gpu_mods):
    """Member names in Python address the rows the GLSL declaration order gives them."""
    layout, _, _ = gpu_mods
    b = layout.LIXEL_SHADE.block()
    b.bias[:] = (1, 2, 3, 4)
    b.maps[2].matrix[:] = np.arange(16).reshape(4, 4)
    b.maps[7].polygon[31] = (9, 9, 9, 9)
    per_map = layout.LIXEL_MAP.rows
    assert tuple(b.rows[8]) == (1, 2, 3, 4)           # the ninth vec4 of LixelShade
    np.testing.assert_array_equal(b.rows[14 + 2 * per_map:14 + 2 * per_map + 4], np.arange(16).reshape(4, 4))
    assert tuple(b.rows[-1]) == (9, 9, 9, 9)
    with pytest.raises(AttributeError):
        b.camera = (0, 0, 0, 0)
