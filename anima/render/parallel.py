"""Frames rendered on several threads, written in order (the rasterizer, OpenCV and numpy's BLAS release the
GIL, so frame-level threads use the cores a single render loop leaves idle)."""

from __future__ import annotations

import os
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor


def ordered_map(fn: Callable, items: Iterable, workers: int | None = None, ahead: int = 2) -> Iterator:
    """``map(fn, items)`` on ``workers`` threads (default: the cores), results in order, at most
    ``workers * ahead`` computed ahead of the consumer (bounded memory for large frames). An exception in
    ``fn`` is raised where its result would have been yielded; the rest is cancelled."""
    workers = workers or max(1, os.cpu_count() or 1)
    if workers <= 1:
        yield from map(fn, items)
        return
    it = iter(items)
    with ThreadPoolExecutor(max_workers=workers) as pool:
        pending: deque = deque()
        try:
            for x in it:
                pending.append(pool.submit(fn, x))
                if len(pending) >= workers * ahead:
                    yield pending.popleft().result()
            while pending:
                yield pending.popleft().result()
        finally:
            for fut in pending:
                fut.cancel()
