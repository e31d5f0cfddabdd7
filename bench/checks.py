"""The benches' criteria: print which hold, write them beside the numbers, give the exit status."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Optional


def report(checks: list[tuple[bool, str]], json_path: Optional[Path], numbers: dict) -> int:
    """Print 'k of n checks hold' and a FAIL line per failed check; with ``json_path``, write
    ``numbers`` and the checks there. Returns the exit status: 0 when every check holds, else 1."""
    failed = [line for ok, line in checks if not ok]
    print(f"\n{len(checks) - len(failed)} of {len(checks)} checks hold")
    for line in failed:
        print("FAIL", line)
    if json_path is not None:
        json_path = Path(json_path)
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps({**numbers, "checks": [{"holds": ok, "what": w} for ok, w in checks]},
                                        indent=1))
    return 1 if failed else 0
