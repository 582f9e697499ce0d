"""``anima eval all``: every evaluation in one run, one results file.

The rows come from the registry (:mod:`anima.eval.registry`): each is one evaluation with one config, run the
way its own command runs it (``anima eval NAME ...``, recorded beside it): its command, the
wall time, its status (``ok``, ``skipped: why`` or ``failed: why``) and its full result. The file also
records what the numbers stand on: the commit of the code (``git rev-parse HEAD`` when the package is a
checkout), the anima version, a fingerprint of the shared data (sha256 over every file's path and content)
and of the dataset folder (its manifest), the machine's cores and Python. A markdown summary with the
headline numbers of every row is written beside it (``summary.md``).

A failing row does not stop the others: its error is recorded and the command exits 3 at the end when any
row failed.
"""

from __future__ import annotations

import hashlib
import json
import multiprocessing
import os
import platform
import subprocess
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

from threadpoolctl import threadpool_limits

from anima import __version__
from anima.errors import AnimaError, InputError, SchemaError
from anima.eval.config import AllEval
from anima.eval.registry import EVALUATIONS, Context, Evaluation
from anima.eval.registry import rows as registry_rows
from anima.io.assets import data_root, shown_path
from anima.io.atomic import write_json, write_text
from anima.io.outdir import OutputFolder, sha256
from anima.io.validate import MAX_JSON_BYTES, MAX_JSON_DEPTH, json_depth


def commit() -> str | None:
    """The code's git commit (with ``-dirty`` when the checkout has changes), or None outside a checkout."""
    root = Path(__file__).resolve().parents[2]
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True, check=True)
        dirty = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"], capture_output=True, text=True
        )
    except (OSError, subprocess.CalledProcessError):
        return None
    return head.stdout.strip() + ("-dirty" if dirty.stdout.strip() else "")


def data_fingerprint(root: Path | None = None) -> dict:
    """sha256 over every file under the data root (relative path, then content), in sorted path order."""
    root = Path(root or data_root())
    h = hashlib.sha256()
    n = size = 0
    for p in sorted(q for q in root.rglob("*") if q.is_file()):
        h.update(str(p.relative_to(root)).encode() + b"\0")
        with open(p, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
                size += len(block)
        n += 1
    return {"root": shown_path(root), "files": n, "bytes": size, "sha256": h.hexdigest()}


BUILD_TIMING = ("compute_s", "last_run")
"""A dataset manifest's fields that say how a build ran (its seconds, its workers), not what it holds."""


def dataset_fingerprint(folder: str | os.PathLike) -> dict:
    """The manifest's sha256, and ``content_sha256``: the sha256 of the manifest without :data:`BUILD_TIMING`
    (keys sorted), equal for two builds of the same data by the same code (what ``--resume`` compares)."""
    m = Path(folder) / "manifest.json"
    if not m.is_file():
        return {"folder": str(folder), "manifest_sha256": None, "content_sha256": None}
    raw = m.read_bytes()
    try:
        held = {k: v for k, v in json.loads(raw).items() if k not in BUILD_TIMING}
        content = hashlib.sha256(json.dumps(held, sort_keys=True).encode()).hexdigest()
    except (ValueError, AttributeError, RecursionError):
        content = None
    return {"folder": str(folder), "manifest_sha256": hashlib.sha256(raw).hexdigest(), "content_sha256": content}


def _same_dataset(a: dict, b: dict) -> bool:
    if a.get("content_sha256") and b.get("content_sha256"):
        return a["content_sha256"] == b["content_sha256"] and a.get("folder") == b.get("folder")
    return a == b


def run_row(ev: Evaluation, name: str, cfg) -> dict:
    """One row as its command runs it: a refusal is recorded as skipped, a failure as failed (never raised)."""
    t0 = time.perf_counter()
    try:
        ev.check(cfg)
        res, status = ev.runner().run(cfg, progress=False), "ok"
    except AnimaError as e:  # a refusal of that evaluation (missing checkpoint, data): recorded, not fatal
        res, status = None, f"skipped: {e}"
    except Exception as e:  # one broken row must not lose the others' results
        res, status = None, f"failed: {type(e).__name__}: {e}"
    return {"command": ev.command(cfg), "status": status, "wall_s": round(time.perf_counter() - t0, 1), "result": res}


THREAD_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS")


def row_threads(jobs: int) -> int:
    """The threads each row of a run with ``--jobs jobs`` gets: the machine's cores // jobs (at least one). A
    function of ``jobs`` alone, so a row gets the same count whether it ran in the first run or alone in a
    resumed one."""
    return max(1, (os.cpu_count() or 1) // max(1, jobs))


def set_threads(threads: int) -> dict:
    """Give this process ``threads`` threads: the environment (torch and numba read it when imported), the
    thread pools already loaded (BLAS, OpenMP: threadpoolctl), torch's intra-op threads and numba's where they
    are imported. Returns what it replaced (for :func:`_restore_threads`)."""
    import sys

    torch, numba = sys.modules.get("torch"), sys.modules.get("numba")
    old = {"env": {v: os.environ.get(v) for v in THREAD_VARS}}  # torch's count read before the pools move it
    old |= {"torch": torch.get_num_threads()} if torch else {}
    old |= {"numba": numba.get_num_threads()} if numba else {}
    old["pools"] = threadpool_limits(threads)
    for var in THREAD_VARS:
        os.environ[var] = str(threads)
    if torch:
        torch.set_num_threads(threads)
    if numba:
        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))  # numba's pool is sized at import
    return old


def _restore_threads(old: dict) -> None:
    import sys

    for var, value in old["env"].items():
        if value is None:
            os.environ.pop(var, None)
        else:
            os.environ[var] = value
    old["pools"].restore_original_limits()
    if "torch" in old:
        sys.modules["torch"].set_num_threads(old["torch"])
    if "numba" in old:
        sys.modules["numba"].set_num_threads(old["numba"])


def _worker_threads(threads: int) -> None:
    """A worker process's start: its share of the cores (:func:`set_threads`), before any row imports torch."""
    set_threads(threads)


def _threads_now() -> int | None:
    """The threads this process's rows run with: torch's where it is loaded, else what the environment says."""
    import sys

    if "torch" in sys.modules:
        return sys.modules["torch"].get_num_threads()
    return int(os.environ.get("OMP_NUM_THREADS", "0")) or None


def _worker_row(ev_name: str, name: str, cfg) -> dict:
    ev = next(e for e in EVALUATIONS if e.name == ev_name)
    return run_row(ev, name, cfg) | {"threads": _threads_now()}


def run_rows(
    rows: list[tuple[Evaluation, str, object]],
    progress: Callable[[str], None] | None = None,
    jobs: int = 1,
    on_row: Callable[[dict], None] | None = None,
) -> dict:
    """Run each row (evaluation, name, config) as its command does; a refusal is recorded as skipped, a
    failure as failed, and neither stops the others. Each row runs with :func:`row_threads` threads (torch,
    numba, BLAS: :func:`set_threads`), a function of ``jobs`` alone: a resumed run's rows, however few are
    left, run as they would have in the first run; each row records its ``threads``. ``jobs`` 1: one after
    another in this process (its thread settings restored after); > 1: side by side in fresh processes (one
    row left as well), the long rows started first. The result keeps the rows' order.
    ``on_row(rows so far)`` after each row ends (the caller saves them: a run stopped later keeps them)."""
    threads = row_threads(jobs)
    if jobs <= 1 or not rows:
        out = {}
        for ev, name, cfg in rows:
            if progress:
                progress(f"{name}: {ev.command(cfg)}")
            old = set_threads(threads)
            try:
                out[name] = run_row(ev, name, cfg) | {"threads": _threads_now()}
            finally:
                _restore_threads(old)
            if on_row:
                on_row(dict(out))
        return out
    order = sorted(rows, key=lambda r: not r[0].long)  # the long evaluations' rows first (a stable sort)
    done = {}
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(jobs, mp_context=ctx, initializer=_worker_threads, initargs=(threads,)) as pool:
        futures = {pool.submit(_worker_row, ev.name, name, cfg): (ev, name, cfg) for ev, name, cfg in order}
        if progress:
            progress(f"{len(rows)} rows in {jobs} processes of {threads} thread(s) each")
        for fut in as_completed(futures):
            ev, name, cfg = futures[fut]
            try:
                done[name] = fut.result()
            except Exception as e:  # the worker process itself died (memory): recorded, the others go on
                done[name] = {"command": ev.command(cfg), "status": f"failed: {type(e).__name__}: {e}", "wall_s": None}
                done[name]["result"] = None
            if progress:
                progress(f"{name}: {done[name]['status'].split(':')[0]} in {(done[name]['wall_s'] or 0) / 60:.1f} min")
            if on_row:
                on_row({n: done[n] for _, n, _ in rows if n in done})
    return {name: done[name] for _, name, _ in rows}


def provenance(db: str | os.PathLike, jobs: int = 1) -> dict:
    return {
        "commit": commit(),
        "anima_version": __version__,
        "data": data_fingerprint(),
        "dataset": dataset_fingerprint(db),
        "machine": {"cores": os.cpu_count(), "python": platform.python_version(), "platform": platform.platform()},
        "jobs": jobs,
    }


def timing_lines(results: dict) -> list[str]:
    """What a run stands on and how long each row took (the head of ``summary.md``; docs render it too)."""
    p = results["provenance"]
    lines = [
        f"commit `{p['commit']}`, anima {p['anima_version']}, shared data sha256 `{p['data']['sha256'][:16]}` "
        f"({p['data']['files']} files), dataset manifest sha256 `{(p['dataset']['manifest_sha256'] or '-')[:16]}`, "
        f"{p['machine']['cores']} cores, {p.get('jobs', 1)} job(s); total {results['wall_s'] / 60:.1f} min"
        + (f" (resumed: {', '.join(results['resumed'])} from a stopped run of it)." if results.get("resumed") else "."),
        "",
        "| evaluation | status | minutes | command |",
        "|---|---|---|---|",
    ]
    for name, e in results["rows"].items():
        minutes = "-" if e["wall_s"] is None else f"{e['wall_s'] / 60:.1f}"
        status = e["status"] if len(e["status"]) <= 90 else e["status"][:87] + "..."
        lines.append(f"| {name} | {status} | {minutes} | `{e['command']}` |")
    return lines


def summary_markdown(results: dict, rows: list[tuple[Evaluation, str, object]]) -> str:
    lines = ["# anima eval all", "", *timing_lines(results)]
    for ev, name, _ in rows:
        e = results["rows"][name]
        if e["status"] != "ok":
            continue
        lines += ["", f"## {name}", ""]
        try:
            lines += ev.runner().summary(e["result"])
        except (KeyError, TypeError, IndexError) as err:  # a summary must never lose the results file
            lines.append(f"(no summary: {type(err).__name__} {err}; see results.json)")
    return "\n".join(lines) + "\n"


def read_results(out: str | os.PathLike) -> dict | list | None:
    """The ``results.json`` of a run into ``out``, what ``--resume`` reads: None when there is none, or it is not
    a regular file or not JSON (its rows run again). One larger than ``MAX_JSON_BYTES`` or nested deeper than
    ``MAX_JSON_DEPTH`` (anima writes 12 levels) is no results file of anima's: a :class:`SchemaError`, before
    anything is computed."""
    p = Path(out) / "results.json"
    nested = SchemaError(
        f"{p}: nested deeper than {MAX_JSON_DEPTH} levels: not the results of `anima eval all` (--resume reads "
        "them; move the file away to start afresh)"
    )
    try:
        if not p.is_file():
            return None
        if p.stat().st_size > MAX_JSON_BYTES:
            raise SchemaError(
                f"{p}: {p.stat().st_size / 2**20:.0f} MB: not the results of `anima eval all` (at most "
                f"{MAX_JSON_BYTES / 2**20:.0f} MB; --resume reads them; move the file away to start afresh)"
            )
        old = json.loads(p.read_text(encoding="utf-8"))
    except RecursionError:
        raise nested from None
    except (OSError, ValueError):  # (UnicodeDecodeError is a ValueError)
        return None
    if json_depth(old, MAX_JSON_DEPTH) > MAX_JSON_DEPTH:
        raise nested
    return old


def finished_rows(out: Path, prov: dict, quick: bool) -> tuple[dict, float]:
    """The rows (name -> entry, status "ok") of a run into ``out`` that stopped, or ended, on the same clean
    commit, shared data, dataset (its content: a rebuild that took other seconds is the same), ``--jobs`` (a
    row's threads follow it: :func:`row_threads`) and ``quick`` as ``prov``, and that run's minutes: what
    ``--resume`` keeps.
    Anything else: none (a results file nested too deeply, :func:`read_results`: a :class:`SchemaError`)."""
    old = read_results(out)
    if old is None:
        return {}, 0.0
    try:
        p = old["provenance"]
        same = (
            prov["commit"] is not None
            and not prov["commit"].endswith("-dirty")
            and p["commit"] == prov["commit"]
            and p["data"] == prov["data"]
            and _same_dataset(p["dataset"], prov["dataset"])
            and p.get("jobs", 1) == prov.get("jobs", 1)
            and old.get("quick") == quick
        )
        if not same:
            return {}, 0.0
        return {n: e for n, e in old["rows"].items() if e["status"] == "ok"}, float(old.get("wall_s") or 0.0)
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return {}, 0.0


def run_all(cfg: AllEval, progress: Callable[[str], None] | None = None, command: str | None = None) -> dict:
    """Run the rows of ``cfg`` (``only``: these by name; ``jobs``: side by side, :func:`run_rows`; ``resume``:
    keep a stopped run's finished rows) into ``cfg.out``: ``results.json`` (provenance, rows, total time)
    and ``summary.md``, written as one result folder (a manifest last)."""
    db, quick, jobs, only = cfg.db, cfg.quick, cfg.jobs, cfg.only or None
    out = Path(cfg.out)
    work = Path(cfg.work) if cfg.work else out / "text2face_work"
    rows = registry_rows(Context(str(db), out, work, quick))
    if only:
        unknown = sorted(set(only) - {name for _, name, _ in rows})
        if unknown:
            known = ", ".join(name for _, name, _ in rows)
            raise InputError(f"unknown evaluation {', '.join(unknown)}; known: {known}")
        rows = [r for r in rows if r[1] in only]
    with OutputFolder(out, kind="eval_all", command=command, inputs=[db]) as od:
        t0 = time.perf_counter()
        prov = provenance(db, jobs)

        kept, before_s = finished_rows(od.path, prov, quick) if cfg.resume else ({}, 0.0)
        kept = {name: kept[name] for _, name, _ in rows if name in kept}
        before_s = before_s if kept else 0.0  # the stopped run's time is part of this one's
        if progress and cfg.resume:
            progress(f"resumed: {', '.join(kept) or 'no row'} kept from the stopped run (same commit and data)")
        todo = [r for r in rows if r[1] not in kept]

        def save_partial(done: dict) -> None:  # rows so far, marked incomplete (no manifest until the end)
            partial = {"provenance": prov, "quick": quick, "complete": False, "resumed": list(kept)}
            partial["rows"] = {name: (kept | done)[name] for _, name, _ in rows if name in kept | done}
            partial["wall_s"] = round(before_s + time.perf_counter() - t0, 1)
            write_json(od.file("results.json"), partial)
            od.journal({"results.json": sha256(od.path / "results.json")})

        results = {"provenance": prov, "quick": quick, "complete": True, "resumed": list(kept)}
        ran = run_rows(todo, progress, jobs, save_partial)
        results["rows"] = {name: (kept | ran)[name] for _, name, _ in rows}
        results["wall_s"] = round(before_s + time.perf_counter() - t0, 1)
        results["failed"] = [n for n, e in results["rows"].items() if e["status"].startswith("failed")]
        write_json(od.file("results.json"), results)
        write_text(od.file("summary.md"), summary_markdown(results, rows))
    return results
