"""Every filter judges a PCF tap that missed P's receiver by one rule (shade_frag.glsl ``lixel_judge``).

A tap whose stored depth lies past the receiver plane on its ray yet nearer the light than P saw something that is no
part of the receiver (docs/papers.md "Grazing, session 23"): the PCF leaves it out. The multiple-depth maps (MDSM,
Pagot et al. §4.2) judge each texel by its own depth, key 0, the one depth whose ray is known; revectorization
(``lixel_run``) reads a tap the PCF left out as the PCF's shadow ("graze2, session 24").
"""
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from test_gpu_shadows import aim, box, camera, light, lx, plane, render, scene  # noqa: F401
from test_grazing_wall import METHODS, ROOT


def reversed_setup(lx, setup):
    """``setup`` with every map's depth negated and tested GREATER: the same nearest surfaces, reversed depths."""
    flip = np.diag([1.0, 1.0, -1.0, 1.0])
    maps = [lx.types.ShadowMap(flip @ m.matrix, m.size, "GREATER", m.role) for m in setup.maps]
    return lx.types.ShadowSetup(maps, setup.diagnostics)


def steep_scene(scene):
    """A ground, a wall whose -y face the sun meets 4 degrees from grazing, and a box over the wall's top that
    shadows both."""
    plane(scene, size=12.0)
    box(scene, "Wall", size=(6.0, 0.2, 2.0), location=(0.0, 1.5, 1.0))
    box(scene, "Caster", size=(1.0, 1.0, 0.5), location=(0.5, 1.2, 3.0))
    cam = camera(scene, (3.0, -8.0, 5.0), (0, 0, 0), res=(160, 120))
    aim(cam, (0.0, 0.5, 0.5))
    sun = light(scene, "SUN", (0, 0, 10), energy=3.0)
    sun.rotation_euler = (math.radians(4.0), 0.0, math.radians(15.0))


@pytest.mark.parametrize("depths", [3, 4])
def test_a_reversed_depth_map_with_several_depths_per_texel_shadows_as_the_plain_map(lx, scene, depths):
    """MDSM keys are stored smaller-nearer whatever the depth test (mdsm_frag.glsl): a GREATER map of the same
    surfaces shadows every pixel as the LESS map does, with the receiver-plane bias judging its taps (its key 0
    was read as 1 - key, and taps it saw were left out as missed)."""
    steep_scene(scene)
    shadow = dict(mdsm_depths=depths)
    plain, _, _, setup, _ = render(lx, scene, map_size=256, shadow=shadow)
    out, *_ = render(lx, scene, map_size=256, shadow=shadow, setup=reversed_setup(lx, setup))
    seen = plain.covered
    assert seen.sum() > 5000 and (plain.shadow_raw[seen] > 0.5).sum() > 300
    differ = np.abs(out.shadow_raw - plain.shadow_raw)[seen] > 0.02
    assert differ.mean() < 1e-3, f"{differ.sum()} of {seen.sum()} pixels shadowed otherwise"


WALL = """
import dataclasses, json, os, sys
from bench.rendered_error import _scratch_env, scene_with_truth
_scratch_env()
import bpy
import numpy as np
from addon.render.engine import render_depsgraph
from bench.edge_footprint import method_settings
from bench.report.lixel import READ
from bench.report.run import comparable_mask
dg, geometry, view, light, gt, _ = scene_with_truth("gen97_00_side_sun", (640, 360))
P, N = gt.points, gt.normals
wall = (np.abs(P[..., 1] + 98.55) < 0.02) & (N[..., 1] > 0.99) & (P[..., 0] > 37.6) & (P[..., 0] < 44.4)
got = {}
for method in sys.argv[1].split(","):
    got[method] = []
    for shadow in json.loads(sys.argv[2]):
        settings = method_settings(method, 512)
        settings = dataclasses.replace(settings, shadow=dataclasses.replace(settings.shadow, **shadow))
        res = render_depsgraph(dg, (640, 360), settings=settings, read=READ)["result"]
        counted = comparable_mask(gt, res) & wall
        got[method].append([int(counted.sum()), int((counted & (gt.shadow != (res.shadow_raw >= 0.5))).sum())])
print(json.dumps(got), flush=True)
os._exit(0)
"""


def wall_wrong(methods, shadows):
    """{method: [(the wall's counted pixels, its wrong ones) per ``shadows`` setting]} on gen97_00_side_sun at 512²
    (test_grazing_wall's wall, shadow edges included)."""
    out = subprocess.run([sys.executable, "-c", WALL, ",".join(methods), json.dumps(shadows)], cwd=ROOT,
                         capture_output=True, text=True, timeout=600)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_revectorized_edges_on_a_grazed_wall_read_its_missed_taps_as_the_pcf_does():
    """gen97_00's wall at n.l = 0.0127 is under a texel wide across the light, so most taps beside a point of it
    missed it, and the bilinear PCF leaves them out. Revectorization followed the texel staircase through them as if
    they were lit and rendered the wall worse than the filter it refines (GMNPR 94 wrong pixels against 69,
    plane_optimal 209 against 107); reading each as the PCF's shadow, as the PCF's division counts it, it renders the
    wall better (47 and 92)."""
    got = wall_wrong(METHODS, [{}, {"revectorize": True}])
    for method, ((counted, bilinear), (_, revectorized)) in got.items():
        assert counted > 5000, f"{method}: the wall must be seen ({counted} pixels)"
        assert revectorized <= bilinear, f"{method}: revectorized {revectorized} wrong pixels, bilinear {bilinear}"
