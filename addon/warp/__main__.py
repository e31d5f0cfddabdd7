"""``python -m addon.warp --method NAME|all CONFIG.json``: the command line lives in addon/cli."""
import sys

from ..cli import main

if __name__ == "__main__":
    sys.exit(main())
