"""Where a command's time goes: a stopwatch of named stages and the process's own age (start-up cost)."""

from __future__ import annotations

import os
import time


def process_age_s() -> float | None:
    """Seconds since this process started (Linux ``/proc``; None elsewhere): what starting the interpreter
    and importing cost before the command's own work began."""
    try:
        with open("/proc/self/stat") as f:
            start_ticks = int(f.read().rsplit(")", 1)[1].split()[19])
        with open("/proc/uptime") as f:
            uptime = float(f.read().split()[0])
        return max(0.0, uptime - start_ticks / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError):
        return None


class Stopwatch:
    """``with sw("load"): ...`` adds the block's wall time to stage ``load``; :meth:`report` gives seconds
    per stage (rounded to ms) with the process's start-up (``start``) and the total."""

    def __init__(self):
        self.start = process_age_s()
        self.t0 = time.perf_counter()
        self.stages: dict[str, float] = {}

    def __call__(self, name: str):
        return _Stage(self, name)

    def report(self) -> dict:
        out = {"start": None if self.start is None else round(self.start, 3)}
        out |= {k: round(v, 3) for k, v in self.stages.items()}
        out["total"] = round((self.start or 0.0) + time.perf_counter() - self.t0, 3)
        return out


class _Stage:
    def __init__(self, sw: Stopwatch, name: str):
        self.sw, self.name = sw, name

    def __enter__(self):
        self.t = time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.sw.stages[self.name] = self.sw.stages.get(self.name, 0.0) + time.perf_counter() - self.t
        return False
