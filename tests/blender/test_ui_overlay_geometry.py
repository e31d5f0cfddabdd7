"""What the overlays draw equals the warp core's geometry: B's faces, the view
frustum, each map's light frustum (inverse projection of the unit cube; where it
reaches through infinity, its part around B) and the warp frustum P. Computed
without drawing, in background mode."""
import importlib
import json
import math
from pathlib import Path

import bpy
import numpy as np
import pytest

from ui_scenes import active_scene


@pytest.fixture(scope="module")
def m(lixel):
    class M:
        pass
    ns = M()
    ns.og = importlib.import_module(f"{lixel.__name__}.addon.ui.overlay_geometry")
    ns.live = importlib.import_module(f"{lixel.__name__}.addon.ui.live")
    ns.warp = importlib.import_module(f"{lixel.__name__}.addon.warp")
    ns.types = importlib.import_module(f"{lixel.__name__}.addon.warp.types")
    ns.geometry = importlib.import_module(f"{lixel.__name__}.addon.warp.geometry")
    ns.describe = importlib.import_module(f"{lixel.__name__}.addon.scene.describe")
    ns.config = importlib.import_module(f"{lixel.__name__}.addon.cli.config")
    return ns


EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def in_clip_volume(matrix, points, rel=1e-7):
    """Which world points ``matrix`` maps into its clip volume: w > 0 and |NDC| <= 1 (to ``rel``)."""
    h = np.c_[np.asarray(points).reshape(-1, 3), np.ones(len(np.asarray(points).reshape(-1, 3)))] @ matrix.T
    return (h[:, 3] > 0) & np.all(np.abs(h[:, :3]) <= (1 + rel) * h[:, 3:], axis=1)


def corners_behind(m, matrix):
    """Whether a clip-volume corner has homogeneous w < 0: the divide by w puts it at a finite, mirrored point."""
    return bool(np.any(m.geometry.clip_volume_corners_h(matrix)[:, 3] < 0))


def polygon_area(poly):
    p = np.asarray(poly)
    return 0.5 * np.linalg.norm(sum(np.cross(p[0], p[i]) + np.cross(p[i], p[i + 1]) + np.cross(p[i + 1], p[0])
                                    for i in range(1, len(p) - 1)))


def triangle_areas(tris):
    return 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)


def check_body(og, geometry, body):
    tris = geometry["body_triangles"]
    # every triangle lies in one face of B and the triangles of a face tile it (same area)
    face_of = []
    for t in tris:
        for i, f in enumerate(body.faces):
            n = np.cross(f[1] - f[0], f[2] - f[0])
            n /= np.linalg.norm(n)
            if np.all(np.abs((t - f[0]) @ n) < 1e-9 * body.scale + 1e-12):
                face_of.append(i)
                break
        else:
            raise AssertionError("a drawn triangle lies on no face of B")
    face_of = np.array(face_of)
    areas = triangle_areas(tris)
    for i, f in enumerate(body.faces):
        assert areas[face_of == i].sum() == pytest.approx(polygon_area(f), rel=1e-9, abs=1e-12)
    # the drawn vertices are exactly B's vertices, and each polygon edge is drawn once
    drawn = np.unique(np.round(tris.reshape(-1, 3), 9), axis=0)
    verts = np.unique(np.round(np.concatenate(body.faces), 9), axis=0)
    np.testing.assert_array_equal(drawn, verts)
    n_edges = sum(len(f) for f in body.faces) // 2
    assert len(geometry["body_edges"]) == n_edges


@pytest.mark.parametrize("light_type", ["SUN", "SPOT", "POINT"])
def test_overlay_geometry_equals_the_warp_core(lixel, m, light_type):
    with active_scene(f"lixel_og_{light_type.lower()}", light=light_type) as scene:
        view, light, bounds = m.describe.describe_scene(bpy.context)
        body = m.warp.intersection_body(view, light, bounds)
        for method in m.warp.METHODS:
            try:
                setup = m.warp.compute(method, view, light, bounds, m.types.WarpOptions(), body=body)
            except m.types.WarpError:
                continue  # a method not built yet
            g = m.og.overlay_geometry(view, setup, body.faces)
            check_body(m.og, g, body)
            np.testing.assert_allclose(g["view_corners"], view.corners(), rtol=0, atol=0)
            assert len(g["light_faces"]) == len(setup.maps)
            bounded = [m.geometry.finite_clip_volume_corners(s.matrix) is not None for s in setup.maps]
            for faces, smap, whole in zip(g["light_faces"], setup.maps, bounded):
                drawn = np.unique(np.concatenate(faces), axis=0)
                assert in_clip_volume(smap.matrix, drawn).all(), method
                if whole:   # a bounded volume's drawn vertices map to the unit cube's corners (w > 0)
                    h = np.c_[drawn, np.ones(len(drawn))] @ smap.matrix.T
                    assert len(drawn) == 8 and np.all(h[:, 3] > 0)
                    np.testing.assert_allclose(np.abs(h[:, :3] / h[:, 3:]), 1.0, atol=1e-6)
            if setup.diagnostics.warp_frustum_corners is not None:
                np.testing.assert_array_equal(g["warp_corners"], setup.diagnostics.warp_frustum_corners)
                assert len(g["warp_lines"]) == 12
            else:
                assert len(g["warp_lines"]) == 0
            # lines are the 12 edges of each hexahedron (a cascade's drawn with its splits)
            drawn = np.concatenate([g["light_lines"], *[split["light_lines"] for split in g["splits"]]])
            assert len(drawn) >= 12 * len(setup.maps) and (len(drawn) == 12 * len(setup.maps) or not all(bounded))
            for a, b in g["view_lines"]:
                assert np.sum(~np.isclose(a, b)) >= 1


def test_live_state_draws_what_the_core_computes(lixel, m):
    with active_scene("lixel_og_live") as scene:
        st = m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        assert st.ok, st.error
        view, light, bounds = m.describe.describe_scene(bpy.context)
        body = m.warp.focused_body(view, light, bounds, scene.lixel.to_settings().warp)   # (as the live state does)
        check_body(m.og, st.geometry, body)
        setup = m.warp.compute(st.method_used, view, light, bounds, scene.lixel.to_settings().warp, body=body)
        for faces, smap in zip(st.geometry["light_faces"], setup.maps):
            np.testing.assert_allclose(np.unique(np.concatenate(faces), axis=0),
                                       np.unique(m.geometry.clip_volume_corners(smap.matrix), axis=0),
                                       rtol=1e-12, atol=1e-12)


def test_projection_centre_and_vectors_from_diagnostics(m):
    view = m.types.View.perspective(np.eye(4), math.radians(60), 1.5, 0.1, 50.0)
    corners = view.corners() + np.array([0.0, 0.0, -1.0])
    diag = m.types.Diagnostics("lispsm", warp_frustum_corners=corners,
                               extra={"projection_centre": [1.0, 2.0, 3.0], "v_p": [0.0, 0.0, -2.0],
                                      "middle_vector": [0.0, 1.0, 0.0]})
    setup = m.types.ShadowSetup([m.types.ShadowMap(view.world_to_clip, (64, 64))], diag)
    faces = [np.array([[0, 0, -1.0], [1, 0, -1.0], [0, 1, -1.0]])]
    g = m.og.overlay_geometry(view, setup, faces)
    np.testing.assert_array_equal(g["warp_corners"], corners)
    np.testing.assert_array_equal(g["points"]["projection_centre"], [1.0, 2.0, 3.0])
    vp = g["vectors"]["v_p"]
    np.testing.assert_array_equal(vp[0], [1.0, 2.0, 3.0])
    d = vp[1] - vp[0]
    np.testing.assert_allclose(d / np.linalg.norm(d), [0, 0, -1.0])
    mv = g["vectors"]["middle_vector"]
    np.testing.assert_allclose(mv[0], np.mean(faces[0], axis=0))


def test_classify_updates(lixel, m):
    overlays = importlib.import_module(f"{lixel.__name__}.addon.ui.overlays")
    with active_scene("lixel_og_updates") as scene:
        m.live.update(scene, bpy.context.evaluated_depsgraph_get())
        seen = []
        original = m.live.update

        def spy(scene_, depsgraph, changed=None, **kw):
            seen.append(set(changed))
            return original(scene_, depsgraph, changed=changed, **kw)

        m.live.update = spy
        try:
            scene.camera.location.x += 0.5
            bpy.context.view_layer.update()
            assert seen and "view" in seen[-1] and "bounds" not in seen[-1]
            st = m.live.state(scene)
            assert "describe bounds" not in st.timings  # the scene bounds were reused
            scene.objects["lixel_og_updates cube"].location.z += 0.5
            bpy.context.view_layer.update()
            assert "bounds" in seen[-1] and "view" not in seen[-1]
            scene.objects["lixel_og_updates light"].rotation_euler.x += 0.1
            bpy.context.view_layer.update()
            assert "light" in seen[-1]
        finally:
            m.live.update = original
        del overlays


def test_footprint_readout_of_a_top_down_sun(m):
    """Camera and sun straight down, both orthographic: one texel of a 20 m /
    2048-texel map spans (20/2048) / (10/1000) pixels of a 10 m / 1000-pixel view."""
    g = m.geometry
    cam_to_world = np.eye(4)
    cam_to_world[:3, 3] = (0.0, 0.0, 10.0)
    view = m.types.View(cam_to_world, g.ortho_matrix(-5, 5, -2.5, 2.5, 1.0, 20.0), 1.0, 20.0, resolution=(1000, 500),
                        orthographic=True)
    light = m.types.Light("SUN", direction=[0.0, 0.0, -1.0])
    light_matrix = g.ortho_matrix(-10, 10, -10, 10, 1.0, 30.0) @ g.look_along(
        np.array([0.0, 0.0, 15.0]), np.array([0.0, 0.0, -1.0]), np.array([0.0, 1.0, 0.0]))
    setup = m.types.ShadowSetup([m.types.ShadowMap(light_matrix, (2048, 2048))], m.types.Diagnostics("uniform"))
    pts = np.array([[0.0, 0.0, 0.0], [1.0, -2.0, 0.0], [-3.0, 1.0, 2.0]])
    fp = m.og.footprint_estimate(setup, view, light, pts)
    assert fp["count"] == 3
    assert fp["median"] == pytest.approx((20 / 2048) / (10 / 1000), rel=1e-9)
    assert fp["max"] == pytest.approx(fp["median"], rel=1e-9)
    # a point no map serves is left out
    assert m.og.footprint_estimate(setup, view, light, np.array([[50.0, 0.0, 0.0]])) is None


def test_a_cascade_draws_each_split_in_its_own_colour(lixel, m):
    """Each split's B, maps and slab of the view frustum, nearest first, in distinct colours."""
    from addon.ui import overlays
    with active_scene("lixel_og_cascade", light="SUN") as scene:
        view, light, bounds = m.describe.describe_scene(bpy.context)
        setup = m.warp.compute("cascade", view, light, bounds, m.types.WarpOptions(cascade_splits=3))
        g = m.og.overlay_geometry(view, setup, m.warp.intersection_body(view, light, bounds).faces)
        extra = setup.diagnostics.extra
        assert len(g["splits"]) == len(extra["splits"]) - 1 == 3
        for i, split in enumerate(g["splits"]):
            corners = split["view_lines"].reshape(-1, 3)
            depth = view.eye_depth(corners)
            assert depth.min() == pytest.approx(extra["splits"][i]) and depth.max() == pytest.approx(extra["splits"][i + 1])
            faces = extra["split_body_faces"][i]
            assert len(split["body_edges"]) == sum(len(f) for f in faces) // 2
        props = type("Props", (), {"show_body": True, "show_frusta": True, "show_warp": False})()
        colours = {c for name, c, _ in overlays.line_sets(props, g) if name.startswith("split")}
        assert len({overlays.COLOURS[c] for c in colours}) == 3


THROUGH_INFINITY = [("sun_behind_camera", "cascade", True), ("terrain_point", "gmnpr", False),
                    ("chess_spot", "glpr", False)]
"""Examples where some map's clip volume passes through infinity (a corner at w < 0), with B focused on the
visible region (as the live state does) or whole: the sun behind the camera's cascade, a point light's and a
spot light's warped map."""


def example_geometry(m, example, method, focused):
    view, light, scene, _ = m.config.parse_config(json.loads((EXAMPLES / f"{example}.json").read_text()))
    options = m.types.WarpOptions(shadow_map_size=1024)              # (as bench.cascade's judge)
    body = (m.warp.focused_body(view, light, scene, options) if focused
            else m.warp.intersection_body(view, light, scene))
    setup = m.warp.compute(method, view, light, scene, options, body=body)
    return setup, body, m.og.overlay_geometry(view, setup, body.faces)


@pytest.mark.parametrize("example,method,focused", THROUGH_INFINITY)
def test_every_drawn_point_of_a_map_lies_in_its_clip_volume(m, example, method, focused):
    """The overlay draws what each map covers (w > 0, |NDC| <= 1), never the mirrored hexahedron that dividing
    corners at w < 0 gives."""
    setup, _body, g = example_geometry(m, example, method, focused)
    assert any(corners_behind(m, s.matrix) for s in setup.maps)       # the case in question
    for faces, smap in zip(g["light_faces"], setup.maps):
        assert faces                                                    # every map is drawn
        assert in_clip_volume(smap.matrix, np.concatenate(faces)).all()
    owner = np.asarray(setup.diagnostics.extra.get("map_splits", np.zeros(len(setup.maps), dtype=int)))
    drawn = [(split["light_lines"], np.flatnonzero(owner == i)) for i, split in enumerate(g["splits"])]
    for lines, maps in drawn or [(g["light_lines"], range(len(setup.maps)))]:
        assert len(lines) >= 12 * len(maps)
        points = lines.reshape(-1, 3)
        assert np.any([in_clip_volume(setup.maps[k].matrix, points) for k in maps], axis=0).all()


def face_planes(faces):
    """Outward unit normals and offsets of convex polygons (Newell's normal)."""
    n = np.array([np.sum(np.cross(f, np.roll(f, -1, axis=0)), axis=0) for f in faces])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return n, np.einsum("ij,ij->i", n, [f.mean(axis=0) for f in faces])


@pytest.mark.parametrize("example,method,focused", THROUGH_INFINITY)
def test_a_volume_through_infinity_is_drawn_as_its_part_within_the_bound(m, example, method, focused):
    """Cut by B's box grown by ``VOLUME_MARGIN``: a point of that box is inside the drawn volume exactly when the
    map covers it, and the drawn volume holds B's part that the map covers."""
    setup, body, g = example_geometry(m, example, method, focused)
    lo, hi = m.og.drawing_bound(body.faces)
    margin = 1e-9 * np.linalg.norm(hi - lo)
    samples = np.random.default_rng(7).uniform(lo, hi, (4000, 3))
    b_vertices = np.concatenate(body.faces)
    behind = [k for k, s in enumerate(setup.maps) if corners_behind(m, s.matrix)]
    assert behind
    for k in behind:
        faces, matrix = g["light_faces"][k], setup.maps[k].matrix
        drawn = np.concatenate(faces)
        assert np.all(drawn >= lo - margin) and np.all(drawn <= hi + margin)
        n, o = face_planes(faces)
        height = samples @ n.T - o                                      # > 0: outside a face's plane
        clear = np.abs(height).min(axis=1) > 1e-6 * np.linalg.norm(hi - lo)
        inside_drawn = np.all(height <= 0, axis=1)
        np.testing.assert_array_equal(inside_drawn[clear], in_clip_volume(matrix, samples[clear], rel=0.0))
        assert inside_drawn.any()
        covered = b_vertices[in_clip_volume(matrix, b_vertices, rel=-1e-6)]
        assert np.all(covered @ n.T - o <= 1e-6 * np.linalg.norm(hi - lo))
