"""Error counts, edge band and flicker on hand-made images."""
import numpy as np
import pytest

from addon.measure.errors import classify, edge_band, error_image, flicker, flicker_split


def test_classify_splits_false_shadow_and_false_light():
    truth = np.zeros((10, 10), bool)
    truth[:, :5] = True                      # left half in shadow, edge between columns 4 and 5
    method = truth.copy()
    method[0, 5] = True                      # false shadow next to the edge
    method[9, 0] = False                     # false light far from the edge
    valid = np.ones_like(truth)
    valid[5, 9] = False
    c = classify(method, truth, valid, band_radius=1)
    assert (c.valid, c.false_shadow, c.false_light, c.true_shadow) == (99, 1, 1, 50)
    assert c.band == 40                      # columns 3..6
    assert (c.band_false_shadow, c.band_false_light) == (1, 0)
    assert c.error_rate == pytest.approx(2 / 99) and c.band_error_rate == pytest.approx(1 / 40)


def test_invalid_pixels_do_not_make_edges():
    truth = np.zeros((4, 4), bool)
    truth[:, 0] = True
    valid = np.ones_like(truth)
    valid[:, 1] = False                       # the only boundary runs through invalid pixels
    assert not edge_band(truth, valid, 1).any()


def test_error_image_colours():
    truth = np.array([[True, False]])
    method = np.array([[False, True]])
    img = error_image(method, truth, np.ones_like(truth))
    assert tuple(img[0, 0]) == (30, 110, 240) and tuple(img[0, 1]) == (220, 30, 30)


def test_flicker_counts_only_where_truth_is_stable():
    truth = np.zeros((3, 2, 2), bool)
    truth[1:, 0, 0] = True                    # truth changes at (0,0) between frames 0 and 1
    method = truth.copy()
    method[1, 1, 1] = True                    # flips at (1,1): 0->1->0, truth stable there
    f = flicker(method, truth, np.ones_like(truth))
    assert f.stable_transitions == 2 * 4 - 1 and f.flips == 2
    assert f.rate == pytest.approx(2 / 7)
    with pytest.raises(ValueError):
        flicker(method[:, :1], truth, truth)


def test_an_edge_that_stands_still_in_the_world_flickers_only_with_the_camera():
    """A shadow edge one pixel off the truth's, fixed in the world, seen by a camera panning one pixel: every pixel it
    crosses counts as pixel flicker, all of it with the maps held (camera), none when only the maps change (world)."""
    truth = np.zeros((2, 4, 8), bool)
    truth[0, :, :3] = True                    # the true edge at column 3 in frame k-1, column 2 after a pan
    truth[1, :, :2] = True
    method = np.zeros_like(truth)
    method[0, :, :4] = True                   # the method's edge a pixel right of the truth's, in the world too
    method[1, :, :3] = True
    held = method[1]                          # the same maps draw frame k exactly as its own did
    same = np.ones((4, 8), bool)
    s = flicker_split(method[0], held, method[1], truth[0], truth[1], same)
    assert (s.transitions, s.flips, s.camera, s.world) == (28, 4, 4, 0)
    assert flicker(method, truth, np.ones_like(truth)).flips == 4
    shimmer = method[1].copy()
    shimmer[0, 3] = True                      # new maps move one texel of the edge: the same point changes state
    s = flicker_split(method[0], held, shimmer, truth[0], truth[1], same)
    assert (s.flips, s.camera, s.world) == (3, 4, 1) and s.flips <= s.camera + s.world
    with pytest.raises(ValueError):
        flicker_split(method[0], held[:2], method[1], truth[0], truth[1], same)


def test_screen_motion_of_a_pan_and_a_sideways_step():
    """Panning by the angle of one pixel at the centre moves a point straight ahead one pixel, however far; a sideways
    step moves a point by its parallax, f·step/depth pixels, so the near one twice as far as one twice as distant."""
    import math
    from addon.measure import screen_motion
    from hard_cases import camera
    before = camera((0, 0, 0), forward=(0, 1, 0), res=(640, 360))
    f_px = before.projection[0][0] * 640 / 2                      # focal length in pixels
    yaw = math.atan(1 / f_px)
    panned = camera((0, 0, 0), forward=(math.sin(yaw), math.cos(yaw), 0), res=(640, 360))
    ahead = np.array([[0, 5, 0], [0, 50, 0]])
    assert screen_motion(before, panned, ahead) == pytest.approx([1, 1], rel=1e-6)
    stepped = camera((0.1, 0, 0), forward=(0, 1, 0), res=(640, 360))
    assert screen_motion(before, stepped, ahead) == pytest.approx([f_px * 0.1 / 5, f_px * 0.1 / 50], rel=1e-9)
