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
