"""Dataset storage: Parquet shards with a versioned schema, one writer and one reader each.

Layout of a dataset folder::

    manifest.json                  schema, version, config, per-video status, filter counts, splits
    stats.json                     normalisation (mean, std) from the training split only
    shards/text_motion/<video>.parquet
    shards/audio_motion/<video>.parquet
    videos/<video>.json            per-video result (its presence marks the video as done)
    errors/<video>.json            the error of a failed video

Schema ``anima.dataset`` version 1. ``text_motion`` rows (one per clip):
clip_id, video_id, split, source (path), start_s, end_s, fps (30), n_frames, motion (list<float32>,
n_frames x 56: 53 ICT expression weights + head axis-angle), texts (list<string>, >= 10), attributes (JSON:
events [name, start_s, end_s] relative to the clip), gender, provenance (JSON: tracker, face model, anima
version, capture settings).
``audio_motion`` rows (one per 64-frame window at 15 fps): window_id, video_id, split, source, start_s, fps,
n_frames, body (64 x 165), face (64 x 56), speech (64 x 28), provenance. Face-only windows (the face and speech
are tracked, the body or hands are not) have an all-NaN body.
Both read with pyarrow, pandas, ``ray.data.read_parquet(folder/shards/<kind>)`` or the torch datasets of
``anima.dataset.torch_data``.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from anima.errors import InputError, SchemaError
from anima.io.atomic import atomic_path
from anima.io.validate import read_json

if TYPE_CHECKING:
    import pyarrow as pa

SCHEMA = "anima.dataset"
VERSION = 1
KINDS = ("text_motion", "audio_motion")


@cache
def schemas() -> dict:
    """``{kind: pyarrow schema}`` (pyarrow loads here, not on import: reading a manifest needs no Arrow)."""
    import pyarrow as pa

    text = pa.schema(
        [
            ("clip_id", pa.string()),
            ("video_id", pa.string()),
            ("split", pa.string()),
            ("source", pa.string()),
            ("start_s", pa.float64()),
            ("end_s", pa.float64()),
            ("fps", pa.float32()),
            ("n_frames", pa.int32()),
            ("motion", pa.list_(pa.float32())),
            ("texts", pa.list_(pa.string())),
            ("attributes", pa.string()),
            ("gender", pa.string()),
            ("provenance", pa.string()),
        ]
    )
    audio = pa.schema(
        [
            ("window_id", pa.string()),
            ("video_id", pa.string()),
            ("split", pa.string()),
            ("source", pa.string()),
            ("start_s", pa.float64()),
            ("fps", pa.float32()),
            ("n_frames", pa.int32()),
            ("body", pa.list_(pa.float32())),
            ("face", pa.list_(pa.float32())),
            ("speech", pa.list_(pa.float32())),
            ("provenance", pa.string()),
        ]
    )
    return {"text_motion": text, "audio_motion": audio}


def write_shard(rows: list[dict], path: Path, kind: str) -> Path:
    """Write rows atomically (temp file + rename): a killed build never leaves a half-written shard."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    schema = schemas()[kind]
    cols = {f.name: [r[f.name] for r in rows] for f in schema}
    for f in schema:
        if pa.types.is_list(f.type) and f.type.value_type == pa.float32():
            cols[f.name] = [np.asarray(v, np.float32).ravel() for v in cols[f.name]]
    table = pa.Table.from_pydict(cols, schema=schema)
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp)
    return path


def check_dataset(folder: str | Path) -> dict:
    folder = Path(folder)
    m = folder / "manifest.json"
    if not folder.is_dir():
        raise InputError(
            f"no dataset at {folder}" if not folder.exists() else f"{folder}: a file, not a dataset folder"
        )
    if not m.is_file():
        raise InputError(f"{folder}: not an anima dataset (no manifest.json)")
    manifest = read_json(m, "dataset manifest")
    if not isinstance(manifest, dict):
        raise SchemaError(f"{m}: not an anima dataset manifest")
    if manifest.get("schema") != SCHEMA:
        raise SchemaError(f"{folder}: schema {manifest.get('schema')!r}, expected {SCHEMA!r}")
    if manifest.get("version") != VERSION:
        raise SchemaError(
            f"{folder}: dataset schema version {manifest.get('version')} (this anima reads "
            f"{VERSION}); rebuild it with `anima dataset build`"
        )
    return manifest


def read_table(folder: str | Path, kind: str, split: str | None = None) -> pa.Table:
    """All shards of ``kind`` (optionally one split) as one pyarrow Table."""
    import pyarrow as pa
    import pyarrow.compute  # for pa.compute
    import pyarrow.parquet as pq

    check_dataset(folder)
    files = sorted((Path(folder) / "shards" / kind).glob("*.parquet"))
    if not files:
        return schemas()[kind].empty_table()
    tables = []
    for f in files:
        try:
            tables.append(pq.read_table(f, schema=schemas()[kind]))
        except (pa.ArrowException, OSError, ValueError) as e:
            raise InputError(
                f"{f}: damaged Parquet shard ({str(e).splitlines()[0][:120]}); rebuild its video with "
                "`anima dataset build` (delete the shard and its videos/*.json first)"
            ) from None
    t = pa.concat_tables(tables)
    if split is not None:
        t = t.filter(pa.compute.equal(t["split"], split))
    return t


def load_stats(folder: str | Path) -> dict:
    p = Path(folder) / "stats.json"
    return read_json(p, "dataset statistics") if p.is_file() else {}
