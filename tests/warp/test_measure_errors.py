"""Error counts, edge band and flicker on hand-made images."""
import numpy as np
import pytest

from addon.measure.errors import classify, edge_band, error_image, flicker


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
