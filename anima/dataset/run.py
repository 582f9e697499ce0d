"""``anima dataset build``: videos -> a dataset folder ((text, motion) clips and (audio, motion) windows), on a
local or a real Ray cluster (:mod:`anima.dataset.build` holds the per-video work and the cluster plumbing)."""

from __future__ import annotations

from pathlib import Path

from anima.dataset.annotations import load_annotations
from anima.dataset.build import build_videos, expand_videos
from anima.dataset.config import BuildConfig
from anima.dataset.storage import check_dataset
from anima.errors import InputError
from anima.io.outdir import check_out_dir, claim_folder, lock_folder, unlock_folder


def run(
    inputs: list[str],
    out_dir: str | Path,
    cfg: BuildConfig | None = None,
    annotations: str | None = None,
    address: str | None = None,
    num_workers: int | None = None,
    progress: bool = True,
    command: str | None = None,
) -> dict:

    cfg = cfg or BuildConfig()
    out = check_out_dir(out_dir, inputs=inputs)
    if cfg.filters.min_s > cfg.filters.max_s:
        raise InputError(f"--min-len {cfg.filters.min_s} is longer than --max-len {cfg.filters.max_s}")
    videos = expand_videos(inputs)
    if not videos:
        raise InputError("no videos found in the given paths")
    missing = [str(p) for p in videos if not p.is_file()]
    if missing:
        raise InputError(
            f"video not found: {missing[0]}" + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else "")
        )
    if (out / "manifest.json").exists():
        check_dataset(out)  # refuses a dataset folder of another schema version
    ann = load_annotations(annotations, [p.stem for p in videos]) if annotations else {}
    claim_folder(out, "dataset", inputs=[*inputs, annotations])
    lock = lock_folder(out)
    try:
        return build_videos(videos, out, cfg, ann, address, num_workers, progress, command)
    finally:
        unlock_folder(lock)
