"""Test setup shared by the plain-Python and the Blender tests."""
import os
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

# Keep Blender's and Mesa's caches and user resources out of $HOME (set before bpy loads).
_scratch = Path(os.environ.get("LIXEL_TEST_SCRATCH") or tempfile.mkdtemp(prefix="lixel-tests-"))
os.environ.setdefault("XDG_CACHE_HOME", str(_scratch / "xdg"))
os.environ.setdefault("BLENDER_USER_RESOURCES", str(_scratch / "blender-user"))


def _hypothesis_draws_fixed_by_each_test() -> None:
    """Hypothesis (from 6.131) also draws the literals of every project module imported so far ("local constants":
    ``hypothesis.internal.conjecture.providers``), so a derandomized test's examples changed with the tests that ran
    before it in the process, and with any literal edited in addon/ or bench/. Its own constants only: each test's
    examples follow from the test alone (hypothesis is pinned in requirements/common.txt; an upgrade that renames
    these fails here, loudly)."""
    from hypothesis.internal.conjecture import providers
    none = providers._local_constants                       # empty: nothing adds to it once this is in place
    providers._get_local_constants = lambda: none


_hypothesis_draws_fixed_by_each_test()
