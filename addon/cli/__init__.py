"""The warp core's command line, ``python -m addon.warp``: a JSON config
(config.py) in, each method's maps and diagnostics as JSON out (output.py,
main.py). Serialisation only, numpy and no bpy; the math stays in addon/warp."""
from .config import ConfigError, parse_config
from .main import main
from .output import setup_json

__all__ = ["ConfigError", "parse_config", "main", "setup_json"]
