"""Timed points a reader can compare: the median of repeats with their min and
max, for Lixel's whole frames and the peers' whole renders alike; and the
agreement of two reports' timings (``python -m bench.report.timing A.json B.json``).

Every run is timed twice over the same span: the CPU time of the whole
process (``time.process_time``: every thread, so Blender's, llvmpipe's
rasterizer threads and Cycles' render threads are all counted) and the wall
clock. This machine is shared (2 cores, software OpenGL, often a load average
of 8-13 from other work): the wall clock then measures the neighbours as much
as the frame (two runs differed by up to 3x), while the CPU time a frame costs
stays within about 10 %. The CPU time is the timed point (the speed axis, the
Pareto front, the agreement check); the wall clock is reported beside it,
with the load average while it was measured.

One timed run says little: a point is the median of ``repeats`` runs, and the
repeats of all Lixel points of a scene are interleaved (round r times every
method and size once) so that a burst of load falls on all of them alike.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path


@dataclass
class Clocks:
    """The two clocks read at the start of a timed span."""

    wall: float
    cpu: float

    @classmethod
    def now(cls) -> "Clocks":
        return cls(time.perf_counter(), time.process_time())

    def since(self) -> tuple[float, float]:
        """(wall seconds, process CPU seconds) since this reading."""
        return time.perf_counter() - self.wall, time.process_time() - self.cpu


@dataclass
class Timing:
    """A timed point in milliseconds: median, min and max of ``repeats`` runs in
    process CPU time (the timed point) and in wall-clock time, the median of
    each stage the timed code reports itself (wall clock), the first run (wall)
    and the 1-minute load average over the repeats."""

    median_ms: float
    min_ms: float
    max_ms: float
    wall_median_ms: float
    wall_min_ms: float
    wall_max_ms: float
    repeats: int
    stages_ms: dict = field(default_factory=dict)
    first_ms: float = float("nan")
    """The first run of the point (wall), before any repeat (shader compilation, uploads); not in the median."""
    load: float = float("nan")

    def to_json(self) -> dict:
        return asdict(self)


def load_average() -> float:
    try:
        return os.getloadavg()[0]
    except OSError:
        return float("nan")


def summarise(runs: list, stages: list = (), first_s: float = float("nan"), load: float = float("nan")) -> Timing:
    """A :class:`Timing` from ``runs`` = [(wall seconds, CPU seconds)] and, per
    run, a dict stage -> wall seconds."""
    if not runs:
        raise ValueError("no timed runs")
    wall = [1000.0 * w for w, _ in runs]
    cpu = [1000.0 * c for _, c in runs]
    names = list(dict.fromkeys(k for st in stages for k in st))
    per_stage = {k: 1000.0 * statistics.median([st.get(k, 0.0) for st in stages]) for k in names}
    return Timing(median_ms=statistics.median(cpu), min_ms=min(cpu), max_ms=max(cpu),
                  wall_median_ms=statistics.median(wall), wall_min_ms=min(wall), wall_max_ms=max(wall),
                  repeats=len(runs), stages_ms=per_stage, first_ms=1000.0 * first_s, load=load)


def timed_points(report: dict, key: str = "median_ms") -> dict:
    """(scene, method, size-or-None) -> ``key`` (default: the CPU median, the
    timed point; ``wall_median_ms``: the wall clock's) of every timed point of a report.json."""
    out = {}
    for scene in report.get("scenes", []):
        for rec in scene.get("methods", []) + scene.get("peers", []):
            t = rec.get("timing")
            if rec.get("status") == "ok" and t and key in t:
                out[(scene["name"], rec["method"], rec.get("size"))] = float(t[key])
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


def agreement(a: dict, b: dict, key: str = "median_ms") -> Agreement:
    pa, pb = timed_points(a, key), timed_points(b, key)
    ratios = {k: max(pa[k], pb[k]) / min(pa[k], pb[k]) for k in pa.keys() & pb.keys() if min(pa[k], pb[k]) > 0}
    return Agreement(ratios=ratios, only_in_one=sorted(map(str, pa.keys() ^ pb.keys())))


def read_report(text: str) -> dict:
    """The report.json at ``text`` (or in the report folder ``text``); a missing, unreadable or other file is an
    argparse error that names it (it was a traceback)."""
    path = Path(text)
    path = path / "report.json" if path.is_dir() else path
    try:
        report = json.loads(path.read_text())
    except OSError as exc:
        raise argparse.ArgumentTypeError(f"cannot read {path}: {exc.strerror}") from None
    except (UnicodeDecodeError, json.JSONDecodeError):
        report = None
    if not isinstance(report, dict) or not isinstance(report.get("scenes"), list):
        raise argparse.ArgumentTypeError(f"{path} is not a report.json of python -m bench.report")
    return report


def _limit(text: str) -> float:
    try:
        limit = float(text)
    except ValueError:
        limit = math.nan
    if not limit >= 1.0:
        raise argparse.ArgumentTypeError(f"{text}: give a ratio of 1 or more, e.g. 1.3")
    return limit


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.report.timing",
                                 description="How two report runs' timed points agree (ratio of their medians).")
    ap.add_argument("first", type=read_report, help="report.json of one run (or its folder)")
    ap.add_argument("second", type=read_report, help="report.json of another run (or its folder)")
    ap.add_argument("--limit", type=_limit, default=1.3, help="exit 1 when a point's ratio exceeds this (default 1.3)")
    ap.add_argument("--all", action="store_true", help="list every point, not only the ten worst")
    args = ap.parse_args(argv)
    a, b = args.first, args.second
    worst_cpu = math.nan
    for key, what in (("median_ms", "CPU time (the timed point)"), ("wall_median_ms", "wall clock")):
        ag = agreement(a, b, key)
        ranked = sorted(ag.ratios.items(), key=lambda kv: -kv[1])
        print(f"{what}:")
        for (scene, method, size), r in ranked if args.all else ranked[:10]:
            print(f"  {r:5.2f}x  {scene} {method}{'' if size is None else f' {size}'}")
        k, worst = ag.worst
        over = sum(r > args.limit for r in ag.ratios.values())
        print(f"  {len(ag.ratios)} points; worst ratio {worst:.2f}x; {over} above {args.limit}x" if k else
              "  no common timed points")
        if key == "median_ms":
            worst_cpu = worst
        if ag.only_in_one:
            print(f"  in one run only: {', '.join(ag.only_in_one)}")
    return 0 if worst_cpu <= args.limit else 1


if __name__ == "__main__":
    sys.exit(main())
