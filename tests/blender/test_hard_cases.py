"""Numerically hard scenes render as their well-conditioned twins (a small part of ``python -m bench.hard_cases``,
which judges every case against ray-cast shadows)."""
import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from bench.hard_cases import Case, build, case_with_truth, cases, check, measure_case  # noqa: E402
from bench.rendered_error import default_settings  # noqa: E402

RESOLUTION = (320, 180)
CASES = cases()


def _render(case, method, size, read):
    from addon.render.engine import render_depsgraph
    _, dg = build(case, RESOLUTION)
    return render_depsgraph(dg, RESOLUTION, settings=default_settings(method, size), read=read)["result"]


def test_a_scene_errs_as_much_at_any_scale_and_far_from_the_origin():
    """Objects, lights and the camera's clip range scaled together by 1e-3 or 1e4, or the whole scene moved 1e5 m
    from the origin (float32 on the GPU): judged against ray-cast shadows, each method errs as at unit scale near the
    origin, and shows every pixel the truth counts."""
    names = ["city_side_sun", "city_side_sun_x0.001", "city_side_sun_x10000", "city_side_sun_offset_1e5"]
    rows = [r for name in names
            for r in measure_case(CASES[name], ["uniform", "lispsm", "cascade"], [1024], RESOLUTION, None, print)]
    assert len(rows) == 12 and 0.001 < rows[0].error < 0.02
    failed = [what for holds, what in check(rows, CASES) if not holds]
    assert not failed, failed


def test_a_floor_and_walls_reach_the_shading_with_their_exact_normals():
    """The pre-pass packs each pixel's normal in 14 + 15 bits of octahedral coordinates; an axis is among the codes,
    so a floor's or a box's face keeps its normal exactly (off by 6e-5 rad before, as much as the light's whole
    incidence when a point light stands 1 mm above the floor)."""
    got = _render(Case("contact", "contact"), "uniform", 256, {"covered", "world_normal"})
    n = got.world_normal[got.covered]
    assert len(n) > 0.9 * got.covered.size
    least = np.sort(np.abs(n), axis=1)[:, :2]
    assert (least == 0.0).all(axis=1).mean() > 0.999, np.percentile(least.max(axis=1), [50, 99])


def test_an_orthographic_view_finer_than_float32_resolves_shows_no_acne():
    """An orthographic camera 2e-5 m wide, 10 m from the scene's centre: its pixels (6e-8 m) and the map's texels are
    finer than float32 positions resolve there (~1e-6 m), so a bias of a texel is below their error. The bias is
    measured in texels no narrower than that: the lit ground shows no false shadow away from the shadow's edge,
    which stays as jagged as the float32 positions are."""
    from addon.measure.errors import edge_band
    from addon.render.engine import render_depsgraph
    dg, view, light, gt = case_with_truth(CASES["contact_ortho_2e-05m"], RESOLUTION)
    got = render_depsgraph(dg, RESOLUTION, settings=default_settings("uniform", 1024), read={"shadow_raw", "covered"})
    away = gt.valid & got["result"].covered & ~edge_band(gt.shadow, gt.valid, 40)
    assert away.sum() > 0.5 * gt.valid.sum() and 0.2 < gt.shadow[away].mean() < 0.8
    false_shadow = away & (got["result"].shadow_raw >= 0.5) & ~gt.shadow
    assert false_shadow.sum() == 0, f"{false_shadow.sum()} of {away.sum()} pixels away from the edge"
