"""What the report tells the terminal while it runs: the current step, how many
are left and an estimate of the time left, a heartbeat during long steps (an
EEVEE render takes tens of seconds on llvmpipe), and Blender's harmless noise
(EGL errors at GPU start, "Read blend", "Fra:1 Mem:...") kept out of the way.

Blender writes that noise with C ``printf`` to file descriptors 1 and 2, below
Python's ``sys.stdout``; :func:`quiet_blender` points both descriptors at a
temporary file for the duration of a call and passes on every line that is not
known noise. Progress lines are written to a duplicate of the terminal's
stdout taken at start, so they still reach it while the descriptors are
redirected.
"""
from __future__ import annotations

import contextlib
import os
import re
import threading
import time
from dataclasses import dataclass, field
from typing import Optional, TextIO

from addon.gpu.context import filtered_c_output

HEARTBEAT_S = 5.0
"""A step that runs longer than this prints a line every HEARTBEAT_S seconds (the brief: no silence over 10 s)."""

NOISE = (
    re.compile(r"EGL Error \(0x[0-9a-fA-F]+\)"),         # Mesa/EGL at GPU start in background mode: harmless
    re.compile(r"\|\s*Read blend:"),                      # 5.0: "00:00.789  blend | Read blend: ..."
    re.compile(r"^Read blend:"),                          # 4.2
    re.compile(r"^Fra:\d+ Mem:"),                         # 4.2 render status lines
    re.compile(r"\|\s*Saved:"),                           # 5.0 image saves (outside any timing)
    re.compile(r"^Saved:"),
    re.compile(r"^\s*Time: \d\d:\d\d"),                   # render summaries
    re.compile(r"^\s*$"),
)
"""Lines Blender prints that say nothing a report user needs (shared notes §1, §8.9)."""


def is_noise(line: str) -> bool:
    return any(p.search(line) for p in NOISE)


def quiet_blender(passthrough: Optional[TextIO] = None):
    """Blender's C output for the block, every line that is not :data:`NOISE`
    passed on to ``passthrough`` (default: the real stderr)."""
    return filtered_c_output(is_noise, passthrough)


def _clock(seconds: float) -> str:
    s = int(round(seconds))
    return f"{s // 60}m{s % 60:02d}s" if s >= 60 else f"{s}s"


@dataclass
class Step:
    """One planned unit of work: ``kind`` groups steps of similar cost for the estimate."""

    kind: str
    label: str
    scene: str = ""


@dataclass
class Progress:
    """Prints ``[elapsed] (k/N, ~T left) label`` for each planned step.

    The estimate of time left sums, over the remaining steps, the mean time of
    the steps of the same kind done so far (before any is done: ``guess_s``
    per kind). A daemon thread prints a heartbeat while a step runs longer than
    :data:`HEARTBEAT_S`; bpy releases the GIL while it renders, so the thread
    runs during EEVEE's renders too.
    """

    plan: list
    guess_s: dict = field(default_factory=dict)
    out: Optional[TextIO] = None
    heartbeat_s: float = HEARTBEAT_S

    def __post_init__(self):
        self.t0 = time.perf_counter()
        self.done: dict = {}
        self.index = 0
        self.out = self.out or os.fdopen(os.dup(1), "w", buffering=1)
        self._lock = threading.Lock()
        self._current: Optional[tuple] = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._beat, name="lixel-report-heartbeat", daemon=True)
        self._thread.start()

    # --- estimate
    def _mean(self, kind: str) -> float:
        got = self.done.get(kind)
        if got:
            return sum(got) / len(got)
        return float(self.guess_s.get(kind, 1.0))

    def seconds_left(self) -> float:
        return sum(self._mean(s.kind) for s in self.plan[self.index:])

    # --- output
    def elapsed(self) -> float:
        return time.perf_counter() - self.t0

    def log(self, message: str) -> None:
        with self._lock:
            self.out.write(f"[{_clock(self.elapsed()):>6}] {message}\n")
            self.out.flush()

    @contextlib.contextmanager
    def step(self, kind: str, label: str, scene: str = "") -> Iterator[None]:
        """Run one planned step (an unplanned step is added to the plan)."""
        if self.index >= len(self.plan) or self.plan[self.index].kind != kind:
            self.plan.insert(self.index, Step(kind, label, scene))
        left = self.seconds_left()
        self.log(f"({self.index + 1}/{len(self.plan)}, ~{_clock(left)} left) {label}")
        t = time.perf_counter()
        with self._lock:
            self._current = (label, t)
        try:
            yield
        finally:
            with self._lock:
                self._current = None
            self.done.setdefault(kind, []).append(time.perf_counter() - t)
            self.index += 1

    def drop(self, scene: str, kind: Optional[str] = None) -> None:
        """Forget the remaining planned steps of ``scene`` (of ``kind`` only, if given): they will not run."""
        self.plan[self.index:] = [s for s in self.plan[self.index:]
                                  if not (s.scene == scene and (kind is None or s.kind == kind))]

    def _beat(self) -> None:
        last_beat, step_start = 0.0, None
        while not self._stop.wait(0.5):
            with self._lock:
                cur = self._current
            if cur is None:
                continue
            label, t = cur
            if t != step_start:
                step_start, last_beat = t, t
            now = time.perf_counter()
            if now - last_beat >= self.heartbeat_s:
                last_beat = now
                self.log(f"    ... {label}: {now - t:.0f} s so far")

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
