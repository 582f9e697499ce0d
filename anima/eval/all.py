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
import os
import platform
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

from anima import __version__
from anima.errors import AnimaError, InputError
from anima.eval.registry import Context, Evaluation
from anima.eval.registry import rows as registry_rows
from anima.io.assets import data_root
from anima.io.atomic import write_json, write_text
from anima.io.outdir import OutputFolder


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
    return {"root": str(root), "files": n, "bytes": size, "sha256": h.hexdigest()}


def dataset_fingerprint(folder: str | os.PathLike) -> dict:
    m = Path(folder) / "manifest.json"
    return {
        "folder": str(folder),
        "manifest_sha256": hashlib.sha256(m.read_bytes()).hexdigest() if m.is_file() else None,
    }


def run_rows(rows: list[tuple[Evaluation, str, object]], progress: Callable[[str], None] | None = None) -> dict:
    """Run each row (evaluation, name, config) as its command does; a refusal is recorded as skipped, a
    failure as failed, and neither stops the others."""
    out = {}
    for ev, name, cfg in rows:
        command = ev.command(cfg)
        if progress:
            progress(f"{name}: {command}")
        t0 = time.perf_counter()
        try:
            ev.check(cfg)
            res, status = ev.runner().run(cfg, progress=False), "ok"
        except AnimaError as e:  # a refusal of that evaluation (missing checkpoint, data): recorded, not fatal
            res, status = None, f"skipped: {e}"
        except Exception as e:  # one broken row must not lose the others' results
            res, status = None, f"failed: {type(e).__name__}: {e}"
        out[name] = {"command": command, "status": status, "wall_s": round(time.perf_counter() - t0, 1), "result": res}
    return out


def provenance(db: str | os.PathLike) -> dict:
    return {
        "commit": commit(),
        "anima_version": __version__,
        "data": data_fingerprint(),
        "dataset": dataset_fingerprint(db),
        "machine": {"cores": os.cpu_count(), "python": platform.python_version(), "platform": platform.platform()},
    }


def summary_markdown(results: dict, rows: list[tuple[Evaluation, str, object]]) -> str:
    p = results["provenance"]
    lines = [
        "# anima eval all",
        "",
        f"commit `{p['commit']}`, anima {p['anima_version']}, shared data sha256 `{p['data']['sha256'][:16]}` "
        f"({p['data']['files']} files), dataset manifest sha256 `{(p['dataset']['manifest_sha256'] or '-')[:16]}`, "
        f"{p['machine']['cores']} cores; total {results['wall_s'] / 60:.1f} min.",
        "",
        "| evaluation | status | minutes | command |",
        "|---|---|---|---|",
    ]
    for _, name, _ in rows:
        e = results["rows"][name]
        lines.append(f"| {name} | {e['status']} | {e['wall_s'] / 60:.1f} | `{e['command']}` |")
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


def run_all(
    db: str,
    out: str | os.PathLike,
    work: str | os.PathLike | None = None,
    quick: bool = False,
    only: list[str] | None = None,
    progress: Callable[[str], None] | None = None,
    command: str | None = None,
) -> dict:
    """Run the rows (``only``: these by name) into ``out``: ``results.json`` (provenance, rows, total time)
    and ``summary.md``, written as one result folder (a manifest last)."""

    out = Path(out)
    work = Path(work) if work else out / "text2face_work"
    rows = registry_rows(Context(str(db), out, work, quick))
    if only:
        unknown = sorted(set(only) - {name for _, name, _ in rows})
        if unknown:
            known = ", ".join(name for _, name, _ in rows)
            raise InputError(f"unknown evaluation {', '.join(unknown)}; known: {known}")
        rows = [r for r in rows if r[1] in only]
    with OutputFolder(out, kind="eval_all", command=command) as od:
        t0 = time.perf_counter()
        results = {"provenance": provenance(db), "quick": quick, "rows": run_rows(rows, progress)}
        results["wall_s"] = round(time.perf_counter() - t0, 1)
        results["failed"] = [n for n, e in results["rows"].items() if e["status"].startswith("failed")]
        write_json(od.file("results.json"), results)
        write_text(od.file("summary.md"), summary_markdown(results, rows))
    return results
