"""Bake anima's built-in motion library (``anima/library/data/builtin.npz`` + ``builtin.json``) from the shared
data: what ``anima text2face PROMPT`` and ``anima gesture SPEECH`` use when no ``--db`` is given.

    .venv/bin/python tools/bake_library.py                  # builds a dataset of the chosen videos (~10 min)
    .venv/bin/python tools/bake_library.py --dataset DS     # or reads one already built from exactly them

It writes with the function of ``anima library build`` (``anima.gesture.library.write_from_pairs``), which bakes a
user's own footage the same way without the licence filter.

The videos: every video under the data root whose repository's licence lets derived data ship with an MIT
project (``anima.library.sources.SOURCES``: PATS, TANGO, CREMA-D, MEAD and the pose data stay out) and whose
video's source falls in the training split (``anima.dataset.splits``), so no validation or test video of an
evaluation is in the library. Only motion parameters and speech features are kept (no pixels, no audio, no
identity shape).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from anima.dataset import splits  # noqa: E402
from anima.dataset.build import expand_videos  # noqa: E402
from anima.io.assets import data_root  # noqa: E402
from anima.io.outdir import sha256  # noqa: E402
from anima.library.builtin import LIBRARY  # noqa: E402
from anima.library.sources import SOURCES, licence_of  # noqa: E402


def chosen_videos(root: Path) -> tuple[list[Path], dict[str, int]]:
    """The library's videos under ``root``, and how many of each left-out kind were skipped."""
    keep, skipped = [], {}
    everything = expand_videos([str(root)])
    table = splits.table(everything, root)  # grouped over all the shared data, as a full build groups them
    for v in everything:
        rel = v.resolve().relative_to(root).as_posix()
        lic, ok = licence_of(rel)
        if not ok:
            skipped[lic] = skipped.get(lic, 0) + 1
        elif table[str(v.resolve())]["split"] != "train":
            skipped["validation or test split"] = skipped.get("validation or test split", 0) + 1
        else:
            keep.append(v)
    return keep, skipped


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default=None, help="data root (default: the project's asset lookup)")
    ap.add_argument("--dataset", default=None, help="a dataset already built from exactly the chosen videos")
    ap.add_argument("--out", default=str(LIBRARY))
    args = ap.parse_args(argv)
    root = Path(args.data or data_root()).resolve()
    videos, skipped = chosen_videos(root)
    if not videos:
        print(f"bake_library: no video to bake under {root}", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        ds = Path(args.dataset) if args.dataset else Path(tmp) / "ds"
        if not args.dataset:
            cmd = [sys.executable, "-m", "anima", "dataset", "build", *map(str, videos), "--out", str(ds)]
            subprocess.run(cmd, check=True)
        return bake(ds, videos, skipped, root, Path(args.out))


def bake(ds: Path, videos: list[Path], skipped: dict, root: Path, out: Path) -> int:
    """The library from the dataset ``ds`` of exactly ``videos``, written by the function ``anima library build``
    writes with (:func:`anima.gesture.library.write_from_pairs`), with the licence table in its provenance."""
    from anima.dataset.windows import read_clips, read_windows
    from anima.gesture.library import write_from_pairs

    clips = read_clips(ds)
    by_path = {str(v.resolve()): v for v in videos}
    unknown = sorted({c.source for c in clips if str(Path(c.source).resolve()) not in by_path})
    if unknown:
        print(f"bake_library: {ds} holds videos that are not the chosen ones: {unknown[:3]}", file=sys.stderr)
        return 2
    rel = {str(v.resolve()): v.resolve().relative_to(root).as_posix() for v in videos}
    manifest = json.loads((ds / "manifest.json").read_text())
    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, text=True).stdout
    provenance = {
        "what": "motion parameters only: ARKit-named expression weights + head rotation per frame (text2face), "
        "55-joint upper body + hands and 28 speech features per frame (gesture); no pixels, audio or identity",
        "videos": len(videos),
        "split_rule": "anima.dataset.splits (by source, key path relative to the data root): training videos only",
        "split_rule_version": splits.rule(),
        "sources": [
            {"path": rel[str(v.resolve())], "licence": licence_of(rel[str(v.resolve())])[0], "sha256": sha256(v)}
            for v in videos
        ],
        "left_out": skipped,
        "licence_table": [{"prefix": p, "licence": lic, "included": ok} for p, lic, ok in SOURCES],
        "dataset_version": manifest.get("version"),
        "baked_with": f"tools/bake_library.py at commit {commit.strip()[:12]}",
    }

    def name_of(src: str) -> str:
        return rel.get(str(Path(src).resolve()), Path(src).name)

    npz, meta, prov = write_from_pairs(out, clips, read_windows(ds), name_of, provenance)
    print(f"{npz} ({npz.stat().st_size / 1e6:.1f} MB), {meta}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
