"""``anima eval all``: every evaluation in one run, one results file.

Each row is one evaluation, run the way its own command runs it (``anima eval NAME ...``): its command, the
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
from dataclasses import dataclass
from pathlib import Path

from anima import __version__
from anima.errors import AnimaError, InputError
from anima.eval.annotations import evaluate_annotations
from anima.eval.body import evaluate_body
from anima.eval.landmarks import evaluate_aflw
from anima.eval.pose import evaluate_pose
from anima.eval.reenact import evaluate as evaluate_reenact
from anima.eval.stability import evaluate_stability
from anima.eval.text2face_prompts import HELDOUT, evaluate_prompts
from anima.io.assets import data_root
from anima.io.atomic import write_json, write_text
from anima.io.outdir import OutputFolder


@dataclass
class Row:
    name: str
    command: str
    run: Callable[[], dict]
    summary: Callable[[dict], list[str]]


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


def run_rows(rows: list[Row], progress: Callable[[str], None] | None = None) -> dict:
    out = {}
    for r in rows:
        if progress:
            progress(f"{r.name}: {r.command}")
        t0 = time.perf_counter()
        try:
            res, status = r.run(), "ok"
        except AnimaError as e:  # a refusal of that evaluation (missing checkpoint, data): recorded, not fatal
            res, status = None, f"skipped: {e}"
        except Exception as e:  # one broken row must not lose the others' results
            res, status = None, f"failed: {type(e).__name__}: {e}"
        out[r.name] = {
            "command": r.command,
            "status": status,
            "wall_s": round(time.perf_counter() - t0, 1),
            "result": res,
        }
    return out


def provenance(db: str | os.PathLike) -> dict:
    return {
        "commit": commit(),
        "anima_version": __version__,
        "data": data_fingerprint(),
        "dataset": dataset_fingerprint(db),
        "machine": {"cores": os.cpu_count(), "python": platform.python_version(), "platform": platform.platform()},
    }


def summary_markdown(results: dict, rows: list[Row]) -> str:
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
    for r in rows:
        e = results["rows"][r.name]
        lines.append(f"| {r.name} | {e['status']} | {e['wall_s'] / 60:.1f} | `{e['command']}` |")
    for r in rows:
        e = results["rows"][r.name]
        if e["status"] != "ok":
            continue
        lines += ["", f"## {r.name}", ""]
        try:
            lines += r.summary(e["result"])
        except (KeyError, TypeError, IndexError) as err:  # a summary must never lose the results file
            lines.append(f"(no summary: {type(err).__name__} {err}; see results.json)")
    return "\n".join(lines) + "\n"


# ---- the rows --------------------------------------------------------------------------------------


def _pct(x) -> str:
    return "-" if x is None else f"{100 * x:.2f} %"


def _landmarks_summary(r: dict) -> list[str]:
    out = [
        "| definition | raw MediaPipe NME | fitted model NME | fit - MediaPipe [95 % over images] |",
        "|---|---|---|---|",
    ]
    for name, v in r["by_definition"].items():
        lo, hi = v["fit_minus_mediapipe_ci95_over_images"]
        out.append(
            f"| {name} | {_pct(v['mediapipe_nme'])} | {_pct(v['fit_nme'])} | [{100 * lo:+.2f}, {100 * hi:+.2f}] |"
        )
    return out + ["", f"{r['detected']} of {r['images']} AFLW2000-3D images."]


def _annotations_summary(r: dict) -> list[str]:
    out = [
        f"Out of sample ({r['protocol']}, {len(r['clips'])} clips).",
        "",
        "| attribute | events | P | R |",
        "|---|---|---|---|",
    ]
    f = lambda x: "-" if x is None else f"{x:.2f}"
    for a, v in r["per_attribute"].items():
        out.append(f"| {a} | {v['labelled_events']} | {f(v['precision'])} | {f(v['recall'])} |")
    return out


def _reenact_summary(r: dict) -> list[str]:
    out = ["| run | SSIM | LPIPS | lip NME | tOF (L2, px) | tLP |", "|---|---|---|---|---|---|"]
    for clip in ("adult_obama", "child_d11"):
        for m in ("base_true_colors", "method1", "method2"):
            v = r[clip][m]
            out.append(
                f"| {clip} {m} | {v['ssim']:.4f} | {v['lpips']:.4f} | {_pct(v['nme_lips'])} | "
                f"{v['tof']:.3f} | {v['tlp']:.4f} |"
            )
    return out + ["", "One video per row: no interval over videos."]


def _gesture_summary(r: dict) -> list[str]:
    k, ci = r["knn"], r.get("knn_ci95_over_videos", {})
    iv = lambda n: f" [{ci[n][0]:.2f}, {ci[n][1]:.2f}]" if n in ci else ""
    out = [
        f"{r['windows']} full-body windows from {r['videos']} videos ({r['minutes_of_audio_motion']:.2f} min); "
        "intervals: 95 % over test videos.",
        "",
        f"k-NN: L1 {k['l1_cm']:.2f} cm{iv('l1_cm')}, wrist jerk {k['jerk']:.1f}{iv('jerk')} (captured "
        f"{k['jerk_captured']:.1f}), beat consistency {k['beat_consistency']:.3f}{iv('beat_consistency')}.",
    ]
    if "knn_cgan" in r:
        m = r["knn_cgan"]["metrics"]
        out.append(
            f"k-NN + cGAN: L1 {m['l1_cm']:.2f} cm, jerk {m['jerk']:.1f}, "
            f"moved {m['l1_to_knn_cm']:.2f} cm from the k-NN."
        )
    if "generator" in r:
        out += [
            "",
            "| generator row | L1 cm | FGD | wrist motion cm | jerk | lip error mm |",
            "|---|---|---|---|---|---|",
        ]
        for name, g in r["generator"]["rows"].items():
            out.append(
                f"| {name} | {g['l1_cm']:.2f} | {g['fgd']:.2f} | {g['wrist_motion_cm']:.2f} | {g['jerk']:.1f} | "
                f"{g['lip_error_mm']:.2f} |"
            )
    out += ["", "| control | satisfied [95 % over videos] |", "|---|---|"]
    for c, v in r["control_adherence"].items():
        if "satisfied_fraction" in v:
            lo, hi = v["satisfied_fraction_ci95_over_videos"]
            out.append(f"| {c} | {100 * v['satisfied_fraction']:.1f} % [{100 * lo:.1f}, {100 * hi:.1f}] |")
    return out


def _prompts_summary(r: dict) -> list[str]:
    out = [f"{r['protocol']['prompts']} prompts x {r['protocol']['seeds']} seeds."]
    for name, m in r["methods"].items():
        out.append(
            f"{name}: lowest event recall {m['min_recall']}, highest false alarm {m['max_false_alarm']}, "
            f"order {m['order']['accuracy']}, count {m['count']['accuracy']}, emotion checks "
            f"{m['emotion_checks']['holds']}/{m['emotion_checks']['of']}, same-motion pairs "
            f"{m['distinct']['same_motion_pairs']} of {m['distinct']['pairs']}."
        )
    return out


def default_rows(db: str, out: Path, work: Path, quick: bool = False) -> list[Row]:
    """Every evaluation, each as its command runs it by default. ``quick``: the learned models' rows with few
    training steps (a check that everything runs, not results)."""

    def gesture():
        from anima.eval.gesture.run import evaluate  # lazy: torch

        steps = dict(refiner_steps=10, generator_steps=10, sync_steps=10) if quick else {}
        return evaluate(db, progress=False, **steps)

    def text2face():
        from anima.eval.text2face import evaluate  # lazy: torch

        r = evaluate(
            db, work, reps=2 if quick else 20, ablations=not quick, steps=20 if quick else None, progress=False
        )
        for m in r["methods"].values():  # the raw samples are for scoring only
            m.pop("generated", None)
        return r

    def prompts(suite=None):
        return evaluate_prompts(db, suite, seeds=1 if quick else 3, progress=False)

    q = " --quick" if quick else ""
    return [
        Row("landmarks", "anima eval landmarks --json", evaluate_aflw, _landmarks_summary),
        Row(
            "stability",
            "anima eval stability --json",
            evaluate_stability,
            lambda r: [
                f"jitter reduction {100 * r['mean_acc_reduction']:.1f} %, error ratio {r['mean_error_ratio']:.3f}."
            ],
        ),
        Row("body", "anima eval body --json", lambda: evaluate_body(progress=False), lambda r: ["See results.json."]),
        Row("annotations", "anima eval annotations --json", evaluate_annotations, _annotations_summary),
        Row("pose", "anima eval pose --json", lambda: evaluate_pose(progress=False), lambda r: ["See results.json."]),
        Row(
            "reenact",
            f"anima eval reenact --out {out / 'reenact'} --json",
            lambda: evaluate_reenact(out / "reenact", progress=False),
            _reenact_summary,
        ),
        Row("gesture", f"anima eval gesture --db {db} --json{q}", gesture, _gesture_summary),
        Row("text2face", f"anima eval text2face {db} --work {work} --json{q}", text2face, lambda r: [r["tables"]]),
        Row(
            "text2face_prompts",
            f"anima eval text2face {db} --prompts --seeds {1 if quick else 3} --json",
            prompts,
            _prompts_summary,
        ),
        Row(
            "text2face_prompts_heldout",
            f"anima eval text2face {db} --prompts {HELDOUT} --seeds {1 if quick else 3} --json",
            lambda: prompts(HELDOUT),
            _prompts_summary,
        ),
    ]


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
    rows = default_rows(db, out, work, quick)
    if only:
        unknown = sorted(set(only) - {r.name for r in rows})
        if unknown:
            raise InputError(f"unknown evaluation {', '.join(unknown)}; known: {', '.join(r.name for r in rows)}")
        rows = [r for r in rows if r.name in only]
    with OutputFolder(out, kind="eval_all", command=command) as od:
        t0 = time.perf_counter()
        results = {"provenance": provenance(db), "quick": quick, "rows": run_rows(rows, progress)}
        results["wall_s"] = round(time.perf_counter() - t0, 1)
        results["failed"] = [n for n, e in results["rows"].items() if e["status"].startswith("failed")]
        write_json(od.file("results.json"), results)
        write_text(od.file("summary.md"), summary_markdown(results, rows))
    return results
