"""A derandomized Hypothesis test draws the same examples whatever ran before it in the process (tests/conftest.py)."""
import importlib

from hypothesis import given, settings, strategies as st


def test_a_derandomized_tests_examples_do_not_depend_on_the_modules_imported_before_it(tmp_path, monkeypatch):
    """Importing a project module with literals in the drawn ranges (as another test's imports would) changes no
    example of a test that runs after it."""
    drawn = []

    @settings(derandomize=True, database=None, max_examples=200, deadline=None)
    @given(st.floats(-10.0, 10.0), st.integers(0, 1000))
    def draws(x, n):
        drawn.append((x, n))

    draws()
    before = list(drawn)
    (tmp_path / "lixel_literals_probe.py").write_text("LITERALS = (7.125, -2.5, 3.75, 999, 123, 456)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    importlib.import_module("lixel_literals_probe")
    drawn.clear()
    draws()
    assert drawn == before
