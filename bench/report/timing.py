"""Timed points a reader can compare: the median of repeats with their min and
max, for Lixel's whole frames and the peers' whole renders alike; and the
agreement of two reports' timings (``python -m bench.report.timing A.json B.json``).

The machine is shared and noisy (2 cores, software OpenGL), so one timed
frame says little: a point is the median of ``repeats`` frames, and the
repeats of all Lixel points of a scene are interleaved (round r times every
method and size once) so that a burst of load falls on all of them alike.
"""
from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path


@dataclass
class Timing:
    """A timed point in milliseconds: median, min and max of ``repeats`` runs,
    and the median of each stage the timed code reports itself."""

    median_ms: float
    min_ms: float
    max_ms: float
    repeats: int
    stages_ms: dict = field(default_factory=dict)
    first_ms: float = float("nan")
    """The first run of the point, before any repeat (shader compilation, uploads); not in the median."""

    def to_json(self) -> dict:
        return asdict(self)


def summarise(seconds: list, stages: list = (), first_s: float = float("nan")) -> Timing:
    """A :class:`Timing` from wall-clock ``seconds`` per run and, per run, a dict
    stage -> seconds."""
    if not seconds:
        raise ValueError("no timed runs")
    ms = [1000.0 * s for s in seconds]
    names = list(dict.fromkeys(k for st in stages for k in st))
    per_stage = {k: 1000.0 * statistics.median([st.get(k, 0.0) for st in stages]) for k in names}
    return Timing(median_ms=statistics.median(ms), min_ms=min(ms), max_ms=max(ms), repeats=len(ms),
                  stages_ms=per_stage, first_ms=1000.0 * first_s)


def timed_points(report: dict) -> dict:
    """(scene, method, size-or-None) -> median ms of every timed point of a report.json."""
    out = {}
    for scene in report.get("scenes", []):
        for rec in scene.get("methods", []) + scene.get("peers", []):
            t = rec.get("timing")
            if rec.get("status") == "ok" and t:
                out[(scene["name"], rec["method"], rec.get("size"))] = float(t["median_ms"])
    return out


@dataclass
class Agreement:
    """How two runs' timed points agree: per point the ratio max/min of the two medians."""

    ratios: dict
    only_in_one: list

    @property
    def worst(self) -> tuple:
        if not self.ratios:
            return (None, math.nan)
        key = max(self.ratios, key=self.ratios.get)
        return key, self.ratios[key]


def agreement(a: dict, b: dict) -> Agreement:
    pa, pb = timed_points(a), timed_points(b)
    ratios = {k: max(pa[k], pb[k]) / min(pa[k], pb[k]) for k in pa.keys() & pb.keys() if min(pa[k], pb[k]) > 0}
    return Agreement(ratios=ratios, only_in_one=sorted(map(str, pa.keys() ^ pb.keys())))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.report.timing",
                                 description="How two report runs' timed points agree (ratio of their medians).")
    ap.add_argument("first", type=Path, help="report.json of one run")
    ap.add_argument("second", type=Path, help="report.json of another run")
    ap.add_argument("--limit", type=float, default=1.3, help="exit 1 when a point's ratio exceeds this (default 1.3)")
    args = ap.parse_args(argv)
    ag = agreement(json.loads(args.first.read_text()), json.loads(args.second.read_text()))
    for key, r in sorted(ag.ratios.items(), key=lambda kv: -kv[1]):
        scene, method, size = key
        print(f"{r:5.2f}x  {scene} {method}{'' if size is None else f' {size}'}")
    key, worst = ag.worst
    print(f"{len(ag.ratios)} points; worst ratio {worst:.2f}x ({' '.join(str(k) for k in key if k is not None)})"
          if key else "no common timed points")
    if ag.only_in_one:
        print(f"in one run only: {', '.join(ag.only_in_one)}")
    return 0 if key and worst <= args.limit else 1


if __name__ == "__main__":
    sys.exit(main())
