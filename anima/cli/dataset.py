"""``anima dataset build``, ``anima dataset report``."""

from __future__ import annotations

from dataclasses import dataclass, field

from anima.cli.common import JsonQuiet, add_args, command_line, emit, group, notes
from anima.cli.options import add_options, config_from_args
from anima.dataset import run as dataset
from anima.dataset.build import build_summary
from anima.dataset.config import BuildConfig, FilterConfig
from anima.dataset.report import write_report

FILTER_OPTIONS = ["min_s", "max_s", "emotion_min_s", "max_yaw_deg", "max_fit_nme"]
BUILD_OPTIONS = ["n_descriptions", "seed", "max_frames", "chunk_s", "chunk_warmup_s"]


@dataclass
class BuildIn:
    videos: list = field(default_factory=list, metadata={"positional": True, "nargs": "+", "metavar": "videos"})
    """video files, folders (searched recursively) or glob patterns"""
    out: str = field(default="", metadata={"required": True, "metavar": "OUT"})
    """dataset folder"""
    annotations: str | None = field(default=None, metadata={"metavar": "ANNOTATIONS"})
    """CelebV-Text style JSON (see anima/dataset/annotations.py)"""
    address: str | None = field(default=None, metadata={"metavar": "ADDRESS"})
    """Ray cluster address (default: a local Ray instance)"""
    workers: int | None = field(default=None, metadata={"range": (1, 256), "metavar": "WORKERS"})
    """local Ray workers (default: all cores)"""


@dataclass
class ReportIn:
    dataset: str = field(default="", metadata={"positional": True, "metavar": "dataset"})
    """a dataset folder from `anima dataset build`"""
    sheets: int = field(default=3, metadata={"range": (0, 100), "metavar": "SHEETS"})
    """contact sheets to draw (0-100)"""


def register(sub) -> None:
    dsub = group(
        sub, "dataset", "build and report (text, motion) and (audio, motion) datasets", "dataset_command", "TOOL"
    )
    db = dsub.add_parser(
        "build",
        help="capture, filter, annotate and store videos as training pairs (Ray)",
        description="One Ray task per video (local Ray by default, --address for a cluster; a video longer "
        "than 1.5 x --chunk-len is tracked by one task per chunk, then joined): "
        "capture, filter (length, action keywords, head yaw, fit error, confidence), annotate "
        "(imported or automatic), describe, and write Parquet shards. Resumable: rerun the same "
        "command after an interruption and finished videos are skipped.",
    )
    add_args(db, BuildIn)
    add_options(db, FilterConfig, FILTER_OPTIONS)
    add_options(db, BuildConfig, BUILD_OPTIONS)
    add_args(db, JsonQuiet)  # --quiet: no progress bars (the summary is still printed)
    db.set_defaults(func=cmd_build)
    dr = dsub.add_parser(
        "report",
        help="markdown/HTML report with plots and contact sheets",
        description="Write DATASET/report/report.md and report.html: clips removed per rule, "
        "attribute distribution, clip lengths, example descriptions, contact sheets.",
    )
    add_args(dr, ReportIn)
    dr.set_defaults(func=cmd_report)


def cmd_build(a) -> int:
    cfg = config_from_args(BuildConfig, a, BUILD_OPTIONS, filters=config_from_args(FilterConfig, a, FILTER_OPTIONS))
    m = dataset.run(
        a.videos,
        a.out,
        cfg,
        annotations=a.annotations,
        address=a.address,
        num_workers=a.workers,
        progress=not a.quiet,
        command=command_line(a),
    )
    emit(build_summary(m), a.json)
    notes([f"failed: {e['source']}: {e['error']}" for e in m["videos_failed"]], "warning")
    notes(m.get("content_groups"), "grouped")  # one recording under two names: one split (anima.dataset.splits)
    return 0


def cmd_report(a) -> int:
    p = write_report(a.dataset, sheets=a.sheets)
    print(f"wrote {p} and {p.with_suffix('.html')}")
    return 0
