"""`anima eval all` gives each row a thread count that depends on --jobs alone (not on how many rows a resumed run
has left), sets it in torch, numba and the BLAS pools, and records it in the row. No real evaluation runs here."""

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor
from types import SimpleNamespace

from threadpoolctl import threadpool_info

from anima.eval import all as eval_all


def _threads_seen() -> dict:
    """The threads a row's code would get: torch's and numba's (imported here, as a row imports them), the
    BLAS / OpenMP pools', the environment's."""
    import numba
    import torch

    return {
        "torch": torch.get_num_threads(),
        "numba": numba.get_num_threads(),
        # numpy's BLAS and torch's OpenMP (OpenCV bundles a single-threaded OpenBLAS: always 1)
        "pools": sorted(
            {p["num_threads"] for p in threadpool_info() if "numpy" in p["filepath"] or "torch" in p["filepath"]}
        ),
        "env": os.environ.get("OMP_NUM_THREADS"),
    }


def _fake(seen: list):
    runner = SimpleNamespace(run=lambda cfg, progress=False: seen.append(_threads_seen()) or {"x": cfg})
    return SimpleNamespace(name="fake", long=False, check=lambda cfg: None, command=lambda cfg: f"fake {cfg}",
                           runner=lambda: runner)  # fmt: skip


def test_a_rows_threads_are_a_function_of_jobs_alone():
    cores = os.cpu_count() or 1
    assert [eval_all.row_threads(j) for j in (1, 2, 64)] == [cores, max(1, cores // 2), max(1, cores // 64)]


def test_rows_run_one_after_another_get_every_core_set_and_recorded_whatever_is_left():
    """--jobs 1: three rows, or the one row a resumed run has left, each runs with every core (torch, numba and
    the BLAS pools set, not just assumed) and records it; the caller's thread settings come back after."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        for n in (3, 1):
            seen = []
            ev = _fake(seen)
            out = eval_all.run_rows([(ev, f"row{i}", i) for i in range(n)], jobs=1)
            want = eval_all.row_threads(1)
            assert [r["threads"] for r in out.values()] == [want] * n and all(r["status"] == "ok" for r in out.values())
            assert all(s["torch"] == want and s["env"] == str(want) for s in seen), seen
            assert all(s["pools"] == [want] for s in seen), seen
            assert torch.get_num_threads() == 1  # restored
    finally:
        torch.set_num_threads(before)


def test_a_worker_of_a_jobs_run_sets_its_share_before_a_row_imports_torch():
    """--jobs 2: each worker process (one row left as well) starts with cores // 2 threads: torch and numba,
    imported by the row after the worker started, and the BLAS pools run with that many."""
    want = eval_all.row_threads(2)
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(1, mp_context=ctx, initializer=eval_all._worker_threads, initargs=(want,)) as pool:
        seen = pool.submit(_threads_seen).result(timeout=300)
    assert seen["torch"] == want and seen["numba"] == want and seen["env"] == str(want), seen
    assert seen["pools"] == [want], seen
