"""Peak memory of anima commands against their input size, and against option values that used to decide it.

Each command runs in a fresh process; its peak resident memory (the largest of it and the processes it
waited for, e.g. ffmpeg) is read with ``getrusage``. Rows pair a small and a larger input of the same command,
and a command with a small and an extreme option value: memory must follow the input, never the option.
Writes benchmarks/results/memory.json and prints a markdown table.

    python benchmarks/bench_memory.py
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from anima.io.assets import asset
from anima.io.atomic import write_json
from anima.io.video import FFMPEG

D0 = "liveportrait-examples/assets/examples/driving/d0.mp4"
PATS = "gesture-video/pats-crops/oliver1_gt.mp4"
WAV = "videoretalking-examples/examples/audio/1.wav"

PROBE = (
    "import resource, subprocess, sys; r = subprocess.run(sys.argv[1:], capture_output=True);"
    "print(r.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)"
)


def peak(argv: list) -> tuple[int, float]:
    """(exit code, peak RSS in MB) of ``anima ARGV`` in a fresh process."""
    out = subprocess.run(
        [sys.executable, "-c", PROBE, sys.executable, "-m", "anima", *map(str, argv)],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    return int(out[0]), round(int(out[1]) / 1024, 1)


def _bomb(path: Path, base: Path) -> Path:
    """A 1.7 MB npz that declares a sequence of 300,000 frames (1.7 GB of landmarks)."""
    with np.load(base) as z:
        meta = json.loads(str(z["meta"]))
    meta["n_frames"] = 300_000
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        import io

        buf = io.BytesIO()
        np.save(buf, np.asarray(json.dumps(meta)))
        zf.writestr("meta.npy", buf.getvalue())
        head = io.BytesIO()
        np.lib.format.write_array_header_1_0(head, {"descr": "<f4", "fortran_order": False, "shape": (300_000, 478, 3)})
        with zf.open("landmarks.npy", "w", force_zip64=True) as fh:
            fh.write(head.getvalue())
            for _ in range(1650):
                fh.write(bytes(1 << 20))
    return path


def _crafted_checkpoints(d: Path) -> dict[str, Path]:
    """The shipped text2face checkpoint with the shipped weights and: a stride-0 view of 1.6 GB in place of a
    tensor; a config describing d_m = 1e7; NaN weights."""
    import torch

    from anima.text2face.generate import SHIPPED

    out = {}
    for name in ("stride0", "big_config", "nan_weights"):
        o = torch.load(SHIPPED, weights_only=True)
        first = next(iter(o["tensors"]["state"]))
        if name == "stride0":
            o["tensors"]["state"][first] = torch.zeros(1).expand(400_000_000)
        elif name == "big_config":
            meta = json.loads(o["meta"])
            meta["config"]["model"]["d_m"] = 10**7
            o["meta"] = json.dumps(meta)
        else:
            o["tensors"]["state"][first].fill_(float("nan"))
        torch.save(o, d / f"{name}.pt")
        out[name] = d / f"{name}.pt"
    return out


def _db_bomb(path: Path) -> Path:
    """A re-enactment database of a few MB whose arrays inflate to gigabytes."""
    import io

    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for name in ("expression", "rotation", "scale", "translation", "video", "frame", "identity", "colors"):
            head = io.BytesIO()
            np.lib.format.write_array_header_1_0(
                head, {"descr": "<f4", "fortran_order": False, "shape": (500_000, 1000)}
            )
            with z.open(f"{name}.npy", "w", force_zip64=True) as fh:
                fh.write(head.getvalue())
                for _ in range(200):
                    fh.write(bytes(1 << 20))
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "memory.json"))
    a = ap.parse_args()
    d = Path(tempfile.mkdtemp(prefix="anima-mem-"))
    d0 = str(asset(D0))
    rows = []

    def row(what, argv, input_desc):
        rc, mb = peak(argv)
        rows.append({"command": what, "input": input_desc, "exit": rc, "peak_mb": mb})
        print(f"| {what} | {input_desc} | {rc} | {mb} |", flush=True)

    print("| command | input | exit | peak MB |\n|---|---|---|---|")
    for n in (20, 160):
        row(
            "capture --no-render",
            ["capture", asset(PATS), "--out", d / f"c{n}", "--max-frames", n, "--no-render", "--quiet"],
            f"{n} frames of oliver1 (256x256, body and hands)",
        )
    seq_small, seq_big = d / "c20" / "capture.npz", d / "c160" / "capture.npz"
    for p in (seq_small, seq_big):
        row("info", ["info", p, "--json"], f"{p.stat().st_size / 1e6:.2f} MB sequence ({p.parent.name[1:]} frames)")
    row("info", ["info", _bomb(d / "bomb.npz", seq_small), "--json"], "1.7 MB crafted npz declaring 1.7 GB (refused)")
    subprocess.run([FFMPEG, "-v", "error", "-y", "-i", str(asset(WAV)), "-t", "2", str(d / "a2.wav")], check=True)
    for fr in ("60", "121"):
        row(
            "audio features --frames",
            ["audio", "features", d / "a2.wav", "--fps", "30", "--frames", fr, "--out", d / "f.npz"],
            f"2 s of speech, --frames {fr}",
        )
    row(
        "audio features --frames",
        ["audio", "features", d / "a2.wav", "--frames", "100000000", "--out", d / "f.npz"],
        "2 s of speech, --frames 1e8 (refused)",
    )
    for fps in ("15", "240"):
        row(
            "export bvh --fps",
            ["export", "bvh", seq_big, "--out", d / "x.bvh", "--fps", fps],
            f"160 frames, --fps {fps}",
        )
    row(
        "export bvh --fps",
        ["export", "bvh", seq_big, "--out", d / "x.bvh", "--fps", "1000000"],
        "160 frames, --fps 1e6 (refused)",
    )
    # the red team's cases: each must stay near the small input's row, refused before allocating
    slow = d / "slow.npz"
    with np.load(seq_small) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays["meta"]))
    meta["fps"] = 0.001
    arrays["meta"] = np.asarray(json.dumps(meta))
    np.savez_compressed(slow, **arrays)
    row(
        "export bvh --fps",
        ["export", "bvh", slow, "--out", d / "y.bvh", "--fps", "240"],
        "20 frames at 0.001 fps, --fps 240 (refused)",
    )
    from anima.text2face.generate import SHIPPED

    for name, path in {"the shipped model": SHIPPED, **_crafted_checkpoints(d)}.items():
        row(
            "text2face --checkpoint",
            ["text2face", "a woman smiles", "--checkpoint", path, "--out", d / f"t_{name}", "--no-video"],
            f"{path.stat().st_size / 1e6:.1f} MB checkpoint: {name}{'' if path == SHIPPED else ' (refused)'}",
        )
    row(
        "reenact --db",
        ["reenact", "--actor", d0, "--target", d0, "--out", d / "r.mp4", "--db", _db_bomb(d / "db.npz")],
        "zip bomb database declaring 16 GB (refused)",
    )
    big = d / "ann.json"
    with open(big, "wb") as fh:
        fh.truncate(300 * 2**20)
    row(
        "dataset build --annotations",
        ["dataset", "build", d0, "--out", d / "ds", "--annotations", big],
        "300 MB annotation file (refused by size)",
    )
    # avatar bombs: node counts bounded, walks linear, the retarget's work on the humanoid's nodes only
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    import hostile_avatars

    av = hostile_avatars.make(d / "hostile")
    row("retarget --avatar", ["retarget", seq_big, "--avatar", asset(hostile_avatars.BASE), "--out", d / "a0.vrm"],
        "the 61 KB humanoid VRM (58 nodes), 160 frames")  # fmt: skip
    for name in ("19k flat nodes", "300k-node bomb", "100k-node chain", "19k-node chain"):
        p = av[name]
        ok = name == "19k flat nodes"
        row("retarget --avatar", ["retarget", seq_big, "--avatar", p, "--out", d / "a1.vrm"],
            f"{p.stat().st_size / 1e6:.1f} MB VRM: {name}{'' if ok else ' (refused)'}, 160 frames")  # fmt: skip
    row("view --avatar", ["view", d / "c160", "--avatar", av["300k-node bomb"], "--static", d / "v1"],
        f"{av['300k-node bomb'].stat().st_size / 1e6:.1f} MB VRM: 300k-node bomb (refused)")  # fmt: skip
    write_json(a.out, {"rows": rows, "note": "peak resident memory of the command and its waited-for children"})


if __name__ == "__main__":
    main()
