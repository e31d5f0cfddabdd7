"""bench.rendered_error's criteria read as the rendered-shadows issue words them."""
from bench.rendered_error import Measurement, check


def _m(method, error, p95, p95_lit, size=2048):
    return Measurement("scene", method, size, error, error / 2, error / 2, p95, p95_lit, 1)


def _warping_wins(ms):
    return [c for c in check(ms) if c.criterion == "warping wins"]


def test_warping_wins_is_checked_where_either_reading_of_the_p95_halves():
    """"Where a warped method's analytic p95 footprint is at most half of uniform's": the p95 over the lit points
    facing the light (the report's) or over every lit point (grazing ones too); where either halves, the error at
    2048² must be at most 0.8x uniform's. Where neither does, nothing is checked."""
    uniform = _m("uniform", 0.001, 4.0, 8.0)
    assert not _warping_wins([uniform, _m("lispsm", 0.002, 2.5, 5.0)])
    for p95, p95_lit in ((2.0, 5.0), (2.5, 4.0)):
        wins, loses = _m("lispsm", 0.0008, p95, p95_lit), _m("gmnpr", 0.00081, p95, p95_lit)
        checks = _warping_wins([uniform, wins, loses])
        assert [(c.method, c.holds) for c in checks] == [("lispsm", True), ("gmnpr", False)]
    assert not _warping_wins([_m("uniform", 0.001, 4.0, 8.0, 1024), _m("lispsm", 0.002, 1.0, 1.0, 1024)])
