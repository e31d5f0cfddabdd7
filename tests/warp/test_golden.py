"""The warp core's matrices are the golden's up to rounding (see tests/warp/golden.py):
every method on the bundled examples, the hard cases and the bench scene."""
from golden import differences, load, snapshot


def test_every_method_gives_the_golden_maps():
    lines = differences(snapshot(), load())
    assert not lines, f"{len(lines)} setups differ from tests/warp/golden.json.gz:\n" + "\n".join(lines[:40])
