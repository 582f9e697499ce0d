"""The exit-code contract on a matrix of bad inputs, generated for every command: missing, empty, random,
truncated and wrong-kind files, unicode paths, crafted npz / JSON / Parquet / checkpoints, out-of-range
numbers, unusable output paths, unsafe live sources. Every case must be refused with exit code 2, 3 or 4 and
exactly one line on stderr (``anima: error: ...``), never a traceback, never accepted."""

import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from anima.io.assets import asset

REPO = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.slow  # hundreds of command runs (about three minutes)
D0 = "liveportrait-examples/assets/examples/driving/d0.mp4"
AVATAR = "avatars/VRMC_materials_mtoon_UV_Animation_Test.vrm"
SPEECH = "videoretalking-examples/examples/audio/1.wav"
PATS = "gesture-video/pats-crops/oliver1_gt.mp4"


def _sequence(path: Path, **meta_edits):
    """A valid tracked sequence (generated face + body), then ``meta_edits`` applied to its meta."""
    from anima.export.framing import generated_sequence
    from anima.io.sequence import write_sequence

    rng = np.random.default_rng(0)
    face = np.concatenate([rng.random((20, 53)) * 0.3, rng.normal(0, 0.05, (20, 3))], 1).astype(np.float32)
    body = rng.normal(0, 0.2, (20, 55, 3)).astype(np.float32)
    write_sequence(generated_sequence(15.0, face=face, body=body), path)
    if meta_edits:
        _edit(path, meta=meta_edits)
    return path


def _edit(path: Path, meta: dict | None = None, arrays: dict | None = None, drop=()):
    with np.load(path) as z:
        d = {k: z[k] for k in z.files}
    m = json.loads(str(d["meta"]))
    m.update(meta or {})
    d["meta"] = np.asarray(json.dumps(m))
    d.update(arrays or {})
    for k in drop:
        d.pop(k)
    np.savez(path, **d)
    return path


def _files(d: Path) -> dict:
    """Generic bad files (and a few good ones to pair with bad options)."""
    from anima.io.video import FFMPEG

    f = {"missing": d / "missing.mp4", "unicode_missing": d / "vidéo manquante ✓.mp4", "dir": d / "a_folder"}
    f["dir"].mkdir()
    _put(f, "empty", d / "empty.mp4").write_bytes(b"")
    _put(f, "random", d / "random.mp4").write_bytes(np.random.default_rng(1).bytes(4096))
    _put(f, "text", d / "notes.mp4").write_text("not a video\n" * 50)
    raw = asset(D0).read_bytes()
    _put(f, "cut", d / "cut.mp4").write_bytes(raw[: len(raw) // 3])
    import cv2

    cv2.imwrite(str(f.setdefault("png", d / "image.png")), np.full((64, 64, 3), 128, np.uint8))
    run = lambda *a: subprocess.run([FFMPEG, "-v", "error", "-y", *a], check=True)
    run("-f", "lavfi", "-i", "sine=f=220:d=1", str(f.setdefault("wav", d / "tone.wav")))
    run("-f", "lavfi", "-i", "color=c=gray:s=2x2:d=1", "-pix_fmt", "yuv420p", str(f.setdefault("tiny", d / "tiny.mp4")))
    run(
        "-f",
        "lavfi",
        "-i",
        "testsrc=size=128x128:rate=10",
        "-t",
        "1",
        "-pix_fmt",
        "yuv420p",
        str(f.setdefault("noface", d / "noface.mp4")),
    )
    run("-i", str(asset(SPEECH)), "-t", "0.3", str(f.setdefault("short_wav", d / "short.wav")))
    f["novideo_audio"] = asset(D0)  # a video without an audio track
    return f


def npz_glb(d: Path, seq: Path) -> Path:
    """A plain glTF (the face of ``seq`` exported as .glb: morph targets, no skin, no VRM)."""
    from anima.export.formats import export_file

    out = d / "face_only.glb"
    return out if out.exists() else export_file("glb", seq, out)


def _put(store: dict, key, path: Path) -> Path:
    store[key] = path
    return path


def _copy(src: Path, dst: Path) -> Path:
    dst.write_bytes(src.read_bytes())
    return dst


def _npz_variants(d: Path) -> dict:
    """Crafted tracked sequences for info / export."""
    v = {}
    base = _sequence(d / "base.npz")
    rng = np.random.default_rng(2)
    _put(v, "zeros", d / "not_a_zip.npz").write_bytes(b"PK\x03\x04" + bytes(100))
    np.savez(v.setdefault("no_meta", d / "no_meta.npz"), x=np.zeros(3))
    np.savez(
        v.setdefault("meta_not_json", d / "meta_not_json.npz"), meta=np.asarray("{nope"), expression=np.zeros((2, 53))
    )
    np.savez(v.setdefault("meta_list", d / "meta_list.npz"), meta=np.asarray("[1, 2]"))
    np.savez(v.setdefault("meta_array", d / "meta_array.npz"), meta=np.arange(4))
    np.savez(v.setdefault("meta_deep", d / "meta_deep.npz"), meta=np.asarray("[" * 100_000 + "]" * 100_000))
    np.savez(v.setdefault("meta_nan", d / "meta_nan.npz"), meta=np.asarray('{"fps": NaN}'))
    for name, edits in {
        "other_schema": {"schema": "someone.else"},
        "newer": {"version": 99},
        "version_text": {"version": "two"},
        "fps0": {"fps": 0},
        "fps_neg": {"fps": -15},
        "fps_str": {"fps": "fast"},
        "frames0": {"n_frames": 0},
        "frames_more": {"n_frames": 21},
        "frames_huge": {"n_frames": 10**9},
        "width0": {"width": 0},
        "names_short": {"expr_names": ["a", "b"]},
        "names_not_list": {"expr_names": "smile"},
    }.items():
        v[name] = _edit(_copy(base, d / f"{name}.npz"), meta=edits)
    arrays = {
        "expr_nan": {"expression": np.full((20, 53), np.nan, np.float32)},
        "expr_inf": {"expression": np.full((20, 53), np.inf, np.float32)},
        "rot_nan": {"rotation": np.full((20, 3), np.nan, np.float32)},
        "scale_short": {"scale": np.ones(19, np.float32)},
        "expr_2d_wrong": {"expression": np.zeros((20, 7), np.float32)},
        "body_joints_wrong": {"body_joints": np.zeros((20, 54, 3), np.float32)},
        "identity_nan": {"identity": np.full(100, np.nan, np.float32)},
        "flags_str": {"flags": np.array(["x"] * 20)},
        "landmarks_bad": {"landmarks": np.zeros((20, 478), np.float32)},
    }
    for name, arr in arrays.items():
        v[name] = _edit(_copy(base, d / f"{name}.npz"), arrays=arr)
    v["missing_arrays"] = _edit(_copy(base, d / "missing_arrays.npz"), drop=("expression",))
    obj = d / "object.npz"
    obj.write_bytes(base.read_bytes())
    with zipfile.ZipFile(obj, "a") as z:  # a pickled object array member
        import io

        buf = io.BytesIO()
        np.save(buf, np.array([{"a": 1}], dtype=object), allow_pickle=True)
        z.writestr("evil.npy", buf.getvalue())
    v["object"] = obj
    bomb = d / "bomb.npz"  # kilobytes that declare gigabytes
    with zipfile.ZipFile(bomb, "w", zipfile.ZIP_DEFLATED) as z:
        meta = json.loads(str(np.load(base)["meta"]))
        meta["n_frames"] = 30_000
        buf = __import__("io").BytesIO()
        np.save(buf, np.asarray(json.dumps(meta)))
        z.writestr("meta.npy", buf.getvalue())
        header = __import__("io").BytesIO()
        np.lib.format.write_array_header_1_0(
            header, {"descr": "<f4", "fortran_order": False, "shape": (30_000, 478, 3)}
        )
        with z.open("landmarks.npy", "w", force_zip64=True) as fh:
            fh.write(header.getvalue())
            zero = bytes(1 << 20)
            for _ in range(165):
                fh.write(zero)
    v["bomb"] = bomb
    data = base.read_bytes()
    _put(v, "truncated", d / "truncated.npz").write_bytes(data[: len(data) // 2])
    _put(v, "random", d / "random.npz").write_bytes(rng.bytes(3000))
    v["face_only"] = _edit(
        _copy(base, d / "face_only.npz"), drop=("body_joints", "body_joints_raw", "body_conf", "body_interpolated")
    )
    v["no_face"] = _edit(_copy(base, d / "no_face.npz"), arrays={"flags": np.ones(20, np.uint8)})
    v["body_all_nan"] = _edit(
        _copy(base, d / "body_nan.npz"), arrays={"body_joints": np.full((20, 55, 3), np.nan, np.float32)}
    )
    return v, base


def _datasets(d: Path) -> dict:
    out = {}
    _put(out, "empty_dir", d / "ds_empty").mkdir()
    for name, text in {
        "bad_json": "{nope",
        "wrong_schema": '{"schema": "x", "version": 1}',
        "old_version": '{"schema": "anima.dataset", "version": 0}',
        "non_utf8": None,
        "list": "[1, 2, 3]",
    }.items():
        p = d / f"ds_{name}"
        p.mkdir()
        if text is None:
            (p / "manifest.json").write_bytes(b'{"schema": "\xff\xfe"}')
        else:
            (p / "manifest.json").write_text(text)
        out[name] = p
    p = d / "ds_corrupt_shard"
    (p / "shards" / "audio_motion").mkdir(parents=True)
    (p / "shards" / "text_motion").mkdir(parents=True)
    (p / "manifest.json").write_text('{"schema": "anima.dataset", "version": 1}')
    (p / "shards" / "audio_motion" / "x.parquet").write_bytes(b"PAR1" + bytes(200))
    (p / "shards" / "text_motion" / "x.parquet").write_bytes(b"PAR1" + bytes(200))
    out["corrupt_shard"] = p
    p = d / "ds_no_windows"
    p.mkdir()
    (p / "manifest.json").write_text('{"schema": "anima.dataset", "version": 1}')
    out["no_windows"] = p
    out["a_file"] = d / "ds_file"
    out["a_file"].write_text("x")
    out["missing"] = d / "ds_missing"
    return out


def _annotations(d: Path) -> dict:
    a = {}
    for name, text in {
        "invalid": "{nope",
        "list": "[]",
        "no_clips": '{"x": 1}',
        "nan": '{"clips": {"d0": {"actions": [["smile", NaN, 2]]}}}',
        "inf": '{"clips": {"d0": {"actions": [["smile", 0, Infinity]]}}}',
        "reversed": '{"clips": {"d0": {"actions": [["smile", 3, 1]]}}}',
        "neg": '{"clips": {"d0": {"actions": [["smile", -1, 1]]}}}',
        "gender": '{"clips": {"d0": {"gender": "robot"}}}',
        "unknown_clip": '{"clips": {"zzz": {"actions": []}}}',
        "deep": '{"clips": ' + "[" * 50_000 + "]" * 50_000 + "}",
        "deep_ok_json": '{"clips": {"d0": {"actions": ' + "[" * 100 + "]" * 100 + "}}}",
    }.items():
        _put(a, name, d / f"ann_{name}.json").write_text(text)
    _put(a, "non_utf8", d / "ann_latin1.json").write_bytes('{"clips": {"d0": {"gender": "mâle"}}}'.encode("latin-1"))
    _put(a, "empty", d / "ann_empty.json").write_bytes(b"")
    big = d / "ann_big.json"  # a sparse 80 MB file: refused by size before reading
    with open(big, "wb") as fh:
        fh.truncate(80 * 2**20)
    a["big"] = big
    a["missing"] = d / "ann_missing.json"
    return a


def _checkpoints(d: Path, files: dict) -> dict:
    import torch

    from anima.io.checkpoint import save_checkpoint
    from anima.text2face.generate import SHIPPED

    c = {k: files[k] for k in ("missing", "empty", "random", "text", "dir")}

    class Evil:
        def __reduce__(self):
            return (open, (str(d / "pwned"), "w"))

    torch.save({"x": Evil()}, c.setdefault("crafted", d / "crafted.pt"))
    save_checkpoint(c.setdefault("other_kind", d / "other_kind.pt"), "pose_lifter", 2, {}, {"state": {}})
    data = SHIPPED.read_bytes()
    _put(c, "truncated", d / "truncated.pt").write_bytes(data[: len(data) // 3])
    old = torch.load(SHIPPED, weights_only=True)
    old["version"] = 99
    torch.save(old, c.setdefault("newer", d / "newer.pt"))
    torch.save(
        {
            "format": "anima.checkpoint",
            "envelope": 1,
            "kind": "gesture_generator",
            "version": 2,
            "meta": "{not json",
            "tensors": {"state": {}},
        },
        c.setdefault("bad_meta", d / "bad_meta.pt"),
    )
    # the red team's checkpoints: a 4 MB file whose tensor is a stride-0 view of gigabytes, NaN and 1e30
    # weights, and a config whose model would be far larger than the weights it carries
    first = next(iter(old["tensors"]["state"]))
    for name, edit in {
        "stride0": lambda o: o["tensors"]["state"].__setitem__(first, torch.zeros(1).expand(400_000_000)),
        "nan_weights": lambda o: o["tensors"]["state"][first].fill_(float("nan")),
        "huge_weights": lambda o: o["tensors"]["state"].__setitem__(
            first, torch.full(o["tensors"]["state"][first].shape, 1e30)
        ),
        "big_config": lambda o: o.__setitem__(
            "meta", json.dumps({**json.loads(o["meta"]), "config": _with_model(json.loads(o["meta"]), d_m=10**7)})
        ),
    }.items():
        o = torch.load(SHIPPED, weights_only=True)
        o["version"] = torch.load(SHIPPED, weights_only=True)["version"]
        edit(o)
        torch.save(o, c.setdefault(name, d / f"{name}.pt"))
    return c


def _with_model(meta: dict, **model) -> dict:
    cfg = dict(meta["config"])
    cfg["model"] = {**cfg["model"], **model}
    return cfg


def _float_wav(path: Path, x: np.ndarray, sr: int = 16000) -> Path:
    """A 32-bit float WAV (format 3), which may hold NaN: the red team's damaged audio."""
    import struct

    data = np.asarray(x, "<f4").tobytes()
    fmt = struct.pack("<IHHIIHH", 16, 3, 1, sr, sr * 4, 4, 32)
    path.write_bytes(
        b"RIFF" + struct.pack("<I", 36 + len(data)) + b"WAVEfmt " + fmt + b"data" + struct.pack("<I", len(data)) + data
    )
    return path


# what the red team's ownership cases must refuse, by the reason they give (a refusal for another reason
# would hide a command that skipped the check)
OWNERSHIP = (
    "did not write", "special file", "an input of this command", "existing file", "expected a .",
    "anima wrote; choose another path", "already holds files", "is a link",
)  # fmt: skip


def _red_team(d: Path, files: dict, npz: dict, base: Path, ck: dict, ds: dict) -> list[tuple[str, list]]:
    """The outside red team's cases: outputs at a user's folder, at an input, beside an input, at a
    special file; memory bombs; NaN; and what used to end in an internal error."""
    from anima.io.video import FFMPEG

    user = d / "user"  # a folder of the user's: nothing in it may change
    user.mkdir()
    (user / "notes.txt").write_text("my notes\n")
    (user / "photo.jpg").write_bytes(b"\xff\xd8\xff" + bytes(100))
    (user / "index.html").write_text("<p>my page</p>\n")
    inputs = d / "inputs"  # a user's folder holding the inputs
    inputs.mkdir()
    clip = _copy(asset(D0), inputs / "clip.mp4")
    seq = _copy(base, inputs / "take.npz")
    wav = _copy(files["wav"], inputs / "voice.wav")
    (inputs / "notes.json").write_text('{"mine": true}\n')  # beside `--out notes.mp4`
    fifo = d / "fifo"
    os.mkfifo(fifo)
    specials = [fifo] + ([Path("/dev/full")] if Path("/dev/full").exists() else [])
    res = d / "res"  # a result folder to view
    res.mkdir()
    _copy(base, res / "capture.npz")
    target = str(asset("styletalk-samples/samples/source_video/video/Obama_clip1.mp4"))
    facemodel_in = d / "fm_nan"  # an ICT OBJ folder whose neutral mesh holds NaN
    facemodel_in.mkdir()
    (facemodel_in / "generic_neutral_mesh.obj").write_text("v nan 0 0\nv 0 1 0\nv 1 0 0\nf 1 2 3\n")
    c = []

    def add(name, *argv):
        c.append((name, [str(a) for a in argv]))

    # outputs: a user's folder, the folder holding the inputs, an input, a special file
    for where, folder in (("user folder", user), ("beside an input", inputs)):
        add(f"own capture --out {where}", "capture", clip, "--out", folder, "--quiet")
        add(f"own text2face --out {where}", "text2face", "a woman smiles", "--out", folder, "--no-video")
        add(f"own gesture --out {where}", "gesture", wav, "--generator", ck["crafted"], "--out", folder)
        add(f"own view --static {where}", "view", res, "--static", folder)
        add(f"own dataset build --out {where}", "dataset", "build", clip, "--out", folder, "--quiet")
        add(f"own train text2face --out {where}", "train", "text2face", ds["corrupt_shard"], "--out", folder)
        add(f"own eval reenact --out {where}", "eval", "reenact", "--out", folder)
        add(f"own eval all --out {where}", "eval", "all", "--db", ds["corrupt_shard"], "--out", folder)
    # single files of anima's own kind only: a user's file of another kind, or of that name, is never replaced
    (user / "notes.pt").write_text("not a checkpoint\n")
    (user / "notes.json").write_text('{"mine": true}\n')
    (user / "notes.npz").write_bytes(b"PK\x05\x06" + bytes(18))
    for name in ("notes.txt", "notes.pt"):
        add(f"own train pose --out user {name}", "train", "pose", "--out", user / name, "--steps", "1")
        add(
            f"own train gesture --out user {name}",
            "train",
            "gesture",
            "--db",
            ds["corrupt_shard"],
            "--out",
            user / name,
        )
    for name in ("notes.txt", "notes.npz"):
        add(f"own facemodel correspondence --out user {name}", "facemodel", "correspondence", "--out", user / name)
    for name in ("index.html", "notes.json"):
        add(f"own facemodel landmarks68 --out user {name}", "facemodel", "landmarks68", "--out", user / name)
    for name in ("notes.txt", "notes.pt"):  # notes.pt: its manifest would be the user's notes.json
        add(
            f"own train text2face --ship user {name}",
            "train",
            "text2face",
            ds["corrupt_shard"],
            "--out",
            d / "t_ship",
            "--ship",
            user / name,
        )
    add("own eval text2face --work user folder", "eval", "text2face", ds["corrupt_shard"], "--work", user)
    add("own eval pose --ablation user folder", "eval", "pose", "--ablation", user)
    for fmt in ("arkit", "glb", "bvh", "vrma"):
        add(f"own export {fmt} --out its input", "export", fmt, seq, "--out", seq)
    vrm = _copy(asset(AVATAR), inputs / "me.vrm")
    add("own retarget --out its avatar", "retarget", seq, "--avatar", vrm, "--out", vrm)
    add("own retarget --out its sequence", "retarget", seq, "--avatar", vrm, "--out", seq)
    add("own retarget --out a user's notes", "retarget", seq, "--avatar", vrm, "--out", user / "notes.txt")
    (inputs / "take.vrm").write_bytes(b"glTF my own avatar")  # a user's file at --out
    add("own retarget --out a user's vrm", "retarget", seq, "--avatar", vrm, "--out", inputs / "take.vrm")
    add("own audio features --out its input", "audio", "features", wav, "--out", wav)
    add("own reenact --out the actor", "reenact", "--actor", clip, "--target", target, "--out", clip)
    add("own reenact --out the record's name", "reenact", "--actor", clip, "--target", target, "--out", d / "r.json")
    add(
        "own reenact --out beside a user's json",
        "reenact",
        "--actor",
        clip,
        "--target",
        target,
        "--out",
        inputs / "notes.mp4",
    )
    add("own capture --out an input", "capture", clip, "--out", clip, "--quiet")
    for sp in specials:
        add(f"own capture --out {sp}", "capture", clip, "--out", sp, "--quiet")
        add(f"own export arkit --out {sp}", "export", "arkit", seq, "--out", sp)
        add(f"own audio features --out {sp}", "audio", "features", wav, "--out", sp)
        add(f"own reenact --out {sp}", "reenact", "--actor", clip, "--target", target, "--out", sp)
        add(f"own train gesture --out {sp}", "train", "gesture", "--db", ds["corrupt_shard"], "--out", sp)
        add(f"own facemodel import --out {sp}", "facemodel", "import", facemodel_in, "--out", sp)
        add(f"own view --static {sp}", "view", res, "--static", sp)
        add(f"own retarget --out {sp}", "retarget", seq, "--avatar", vrm, "--out", sp)
        add(f"own live --record {sp}", "live", clip, "--no-browser", "--record", sp)
    add("own live --record a user's folder", "live", clip, "--no-browser", "--record", user)
    add("view --avatar missing", "view", res, "--avatar", d / "none.vrm", "--static", d / "v_av1")
    add("view --avatar a text file", "view", res, "--avatar", files["text"], "--static", d / "v_av2")
    add("view --motion without --avatar", "view", res, "--motion", "vrma", "--static", d / "v_av3")
    add("view --motion vrma onto a glTF", "view", res, "--avatar", npz_glb(d, base), "--motion", "vrma", "--static",
        d / "v_av4")  # fmt: skip
    # memory: bounded by the input before anything is allocated
    slow = _edit(_copy(base, d / "slow_fps.npz"), meta={"fps": 0.001})
    add(
        "mem export bvh of a 0.001-fps sequence at 240 fps",
        "export",
        "bvh",
        slow,
        "--out",
        d / "slow.bvh",
        "--fps",
        "240",
    )
    for k in ("stride0", "nan_weights", "huge_weights", "big_config"):
        add(
            f"mem text2face --checkpoint {k}",
            "text2face",
            "a woman smiles",
            "--checkpoint",
            ck[k],
            "--out",
            d / f"t_{k}",
        )
    bomb = d / "db_bomb.npz"  # a reenact database whose arrays inflate to gigabytes
    with zipfile.ZipFile(bomb, "w", zipfile.ZIP_DEFLATED) as z:
        import io

        for name in (
            "expression",
            "rotation",
            "scale",
            "translation",
            "video",
            "frame",
            "identity",
            "colors",
            "vertex_ids",
            "meta",
        ):
            head = io.BytesIO()
            np.lib.format.write_array_header_1_0(
                head, {"descr": "<f4", "fortran_order": False, "shape": (200_000, 2000)}
            )
            with z.open(f"{name}.npy", "w", force_zip64=True) as fh:
                fh.write(head.getvalue())
                for _ in range(40):
                    fh.write(bytes(1 << 20))
    add(
        "mem reenact --db zip bomb", "reenact", "--actor", clip, "--target", target, "--out", d / "rb.mp4", "--db", bomb
    )
    # NaN and absurd values: refused at load
    nan_wav = _float_wav(d / "nan.wav", np.where(np.arange(16000) % 100 == 0, np.nan, 0.1))
    add("nan audio features", "audio", "features", nan_wav, "--out", d / "nan.npz")
    add("nan capture --audio", "capture", clip, "--out", d / "c_nan", "--audio", nan_wav, "--quiet")
    add("nan gesture speech", "gesture", nan_wav, "--generator", ck["missing"], "--out", d / "g_nan")
    huge = _edit(_copy(base, d / "expr_huge.npz"), arrays={"expression": np.full((20, 53), 1e30, np.float32)})
    add("nan export arkit of 1e30 weights", "export", "arkit", huge, "--out", d / "huge.csv")
    far = _edit(_copy(base, d / "body_far.npz"), arrays={"body_joints": np.full((20, 55, 3), 1e32, np.float32)})
    add("nan export bvh of 1e32 joints", "export", "bvh", far, "--out", d / "far.bvh")
    slow_video = d / "slow.mp4"
    subprocess.run(
        [
            FFMPEG,
            "-v",
            "error",
            "-y",
            "-f",
            "lavfi",
            "-i",
            "testsrc=size=64x64:rate=1",
            "-frames:v",
            "3",
            "-vf",
            "setpts=1000*PTS",
            "-r",
            "0.001",
            "-pix_fmt",
            "yuv420p",
            str(slow_video),
        ],
        check=True,
    )
    add("mem capture of a 0.001-fps video", "capture", slow_video, "--out", d / "c_slow", "--quiet")
    add("nan facemodel import of NaN vertices", "facemodel", "import", facemodel_in, "--out", d / "fm.npz")
    # what used to be an internal error
    add(
        "exit1 info of a meta whose source is text",
        "info",
        _edit(_copy(base, d / "src_text.npz"), meta={"source": "x"}),
        "--json",
    )
    rec_dir = d / "rec"
    rec_dir.mkdir()
    (rec_dir / "r.json").write_text('{"schema": "anima.reenact_run", "version": 1, "actor": "a"}')
    add("exit1 view of a reenact record without result", "view", rec_dir / "r.json", "--static", d / "v_rec")
    add("exit1 text2face --seed 2**64", "text2face", "a woman smiles", "--seed", str(2**64), "--out", d / "t_seed")
    add(
        "exit1 text2face 10^12 blinks",
        "text2face",
        "she blinks 1000000000000 times",
        "--out",
        d / "t_many",
        "--no-video",
    )
    add(
        "exit1 dataset build --address of a closed port",
        "dataset",
        "build",
        clip,
        "--out",
        d / "ds_addr",
        "--address",
        "127.0.0.1:9",
    )
    add(
        "exit1 train gesture --seed 2**64",
        "train",
        "gesture",
        "--db",
        ds["corrupt_shard"],
        "--seed",
        str(2**64),
        "--out",
        d / "s.pt",
    )
    c += _second_pass(d, base, user, inputs, clip, target)
    return c


def _results(d: Path, base: Path) -> Path:
    """A user's results made by anima: a capture result holding a nested text2face result and a
    dataset folder, each with anima's marker and manifest."""
    from anima.export.formats import export_file
    from anima.io.atomic import write_json
    from anima.io.outdir import OutputFolder

    res = d / "results"
    with OutputFolder(res, kind="capture") as od:
        _copy(base, od.file("capture.npz"))
        export_file("glb", base, od.file("face.glb"))
        export_file("arkit", base, od.file("arkit.csv"))
        write_json(od.file("info.json"), {"frames": 20})
    with OutputFolder(res / "t2f", kind="text2face") as od:
        _copy(base, od.file("motion.npz"))
    with OutputFolder(res / "ds", kind="dataset") as od:
        write_json(od.file("notes.json"), {"clips": 0})
    return res


def _second_pass(d: Path, base: Path, user: Path, inputs: Path, clip: Path, target: str) -> list:
    """Reproducers: an output equal to, inside or around an input; single files of the user's (with
    the format's suffix, or not); a take into an existing result; hostile avatars and node bombs; addresses and
    frame rates of the wrong type; a crafted part of a take."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    import hostile_avatars

    res = _results(d, base)
    c = []

    def add(name, *argv):
        c.append((name, [str(a) for a in argv]))

    add("own view RESULT --static RESULT", "view", res, "--static", res)
    add("own view RESULT --static RESULT/t2f", "view", res, "--static", res / "t2f")
    add("own view RESULT/t2f --static RESULT", "view", res / "t2f", "--static", res)
    add("own view RESULT --static RESULT/ds", "view", res, "--static", res / "ds")
    add("own train text2face --out inside its dataset", "train", "text2face", res / "ds", "--out", res / "ds" / "run")
    add("own live --record an existing result", "live", clip, "--no-browser", "--record", res, "--max-frames", "2")
    (user / "take.csv").write_text("Timecode,BlendShapeCount\n12:03:44:01.250,61\n")  # a phone's take
    (user / "take.bvh").write_text("HIERARCHY\nROOT Hips\n{\n}\nMOTION\nFrames: 0\n")
    (user / "my.glb").write_bytes(b"glTF my own model")
    (user / "my_video.mp4").write_bytes(b"\x00\x00\x00\x18ftypmp42 my holiday")
    (user / "my_video.json").write_text('{"schema": "anima.reenact_run", "video_sha256": "0"}')
    for fmt, names in {
        "arkit": ("notes.txt", "take.csv"), "bvh": ("notes.txt", "take.bvh"), "vrma": ("notes.json", "my.glb"),
        "avatar": ("my.glb", "notes.txt"), "glb": ("my.glb", "index.html"),
    }.items():  # fmt: skip
        for name in names:
            add(f"own export {fmt} --out user {name}", "export", fmt, base, "--out", user / name)
    add("own reenact --out a user's video", "reenact", "--actor", clip, "--target", target, "--out",
        user / "my_video.mp4")  # fmt: skip
    add("own export arkit --out a link", "export", "arkit", base, "--out", _link(d, user / "take.csv"))

    # hostile avatars: every one through retarget, a few through view --avatar and live --avatar
    av = hostile_avatars.make(d / "hostile")
    av.pop("19k flat nodes")  # accepted (retargeted in seconds): tests/export/test_retarget.py
    for k, (name, path) in enumerate(av.items()):
        add(f"avatar retarget {name}", "retarget", base, "--avatar", path, "--out", d / "ha" / f"{k}.vrm")
    for name in ("children true", "300k-node bomb", "100k-node chain", "humanBones a list", "scale 0", "cycle"):
        add(f"avatar view --avatar {name}", "view", res, "--avatar", av[name], "--static", d / "hv" / name[:8])
        add(f"avatar live --avatar {name}", "live", clip, "--no-browser", "--avatar", av[name], "--max-frames", "2")

    # addresses parsed by the standard library; frame rates of the wrong type
    for to in ("127.0.0.1:\u0661\u0661\u0661", "127.0.0.1:" + "9" * 5000, "a" * 300 + ".example:9",
               "[::1:9", "user@127.0.0.1:9", "127.0.0.1:9/x"):  # fmt: skip
        add(f"address livelink --to {to[:20]!r}", "livelink", base, "--to", to)
        add(f"address live --livelink {to[:20]!r}", "live", clip, "--no-browser", "--livelink", to)
    for name, fps in (("true", True), ("text 25", "25"), ("0.5", 0.5), ("2000", 2000), ("list", [25])):
        seq = _edit(_copy(base, d / f"fps_{name.replace(' ', '_')}.npz"), meta={"fps": fps})
        add(f"fps {name} info", "info", seq, "--json")
        add(f"fps {name} export bvh", "export", "bvh", seq, "--out", d / "fps.bvh")
    add("mem live --recover a crafted part", "live", "--recover", _crafted_take(d, base))
    return c


def _link(d: Path, target: Path) -> Path:
    link = d / "link.csv"
    link.symlink_to(target)
    return link


def _crafted_take(d: Path, base: Path) -> Path:
    """A killed take's folder whose one part declares 2.7 GB of body in a few KB (listed in anima's marker)."""
    from anima.io.outdir import sha256, write_marker

    folder = d / "take_bomb"
    (folder / "take").mkdir(parents=True)
    part = folder / "take" / "part-00001.npz"
    with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
        import io

        for name, shape, dtype in (("index", (4_000_000,), "<i8"), ("t_capture", (4_000_000,), "<f8"),
                                   ("face", (4_000_000,), "|b1"), ("expression", (4_000_000, 53), "<f4"),
                                   ("rotation", (4_000_000, 3), "<f4"), ("body", (4_000_000, 55, 3), "<f4"),
                                   ("has_body", (4_000_000,), "|b1"), ("fps", (), "<f8")):  # fmt: skip
            head = io.BytesIO()
            np.lib.format.write_array_header_1_0(head, {"descr": dtype, "fortran_order": False, "shape": shape})
            with z.open(f"{name}.npy", "w", force_zip64=True) as fh:
                fh.write(head.getvalue())
                for _ in range(4):
                    fh.write(bytes(1 << 20))
    write_marker(folder, "capture", {"take/part-00001.npz": sha256(part)})
    return folder


NUM_BAD = ["0", "-1", "nan", "inf", "abc", "1e30"]


def cases(d: Path) -> list[tuple[str, list, dict]]:
    files = _files(d)
    npz, base = _npz_variants(d)
    ds = _datasets(d)
    ann = _annotations(d)
    ck = _checkpoints(d, files)
    d0, speech, pats = str(asset(D0)), str(asset(SPEECH)), str(asset(PATS))
    out = d / "out"
    c = []

    def add(name, *argv, env=None):
        c.append((name, [str(a) for a in argv], env or {}))

    video_bad = ["missing", "unicode_missing", "dir", "empty", "random", "text", "cut", "png", "wav", "tiny", "noface"]
    for k in video_bad:
        add(f"capture video {k}", "capture", files[k], "--out", out / f"c_{k}", "--quiet", "--no-render")
        add(f"capture face-only video {k}", "capture", files[k], "--out", out / f"cf_{k}", "--face-only", "--quiet")
    for k in ("missing", "dir", "empty", "random", "text", "png", "novideo_audio"):
        add(f"capture --audio {k}", "capture", d0, "--out", out / f"ca_{k}", "--audio", files[k], "--quiet")
    neutral = {k: files[k] for k in ("missing", "dir", "empty", "random", "text", "png", "noface")}
    neutral |= {"generated sequence": base, "damaged sequence": npz["zeros"], "meta_nan": npz["meta_nan"]}
    for k, f in neutral.items():  # the rest clip: refused before the capture, or once its face is found missing
        add(f"capture --neutral {k}", "capture", d0, "--out", out / "c_neutral", "--neutral", f, "--quiet")
    for opt in ("--sigma", "--max-frames", "--max-gap"):
        for v in NUM_BAD:
            if v == "0" and opt in ("--sigma", "--max-gap"):  # valid: no smoothing, no gap filling
                continue
            add(f"capture {opt} {v}", "capture", d0, "--out", out / "c_opt", opt, v, "--quiet")
    add("capture --body-3d bogus", "capture", d0, "--out", out / "c3", "--body-3d", "bogus")
    add(
        "capture lifter missing model",
        "capture",
        pats,
        "--out",
        out / "c4",
        "--body-3d",
        "lifter",
        "--pose-model",
        files["missing"],
    )
    add(
        "capture lifter crafted model",
        "capture",
        pats,
        "--out",
        out / "c5",
        "--body-3d",
        "lifter",
        "--pose-model",
        ck["crafted"],
    )
    add("capture lifter face-only", "capture", pats, "--out", out / "c6", "--body-3d", "lifter", "--face-only")
    add("capture --out is a file", "capture", d0, "--out", files["text"], "--quiet")
    add("capture --out in /proc", "capture", d0, "--out", "/proc/anima-out/x", "--quiet")
    add("capture no --out", "capture", d0)
    add("capture two videos", "capture", d0, d0, "--out", out / "c7")

    seq_bad = [k for k in npz if k not in ("face_only", "no_face", "body_all_nan")]
    for k in seq_bad + ["missing_file", "dir_file", "empty_file"]:
        other = {"missing_file": files["missing"], "dir_file": files["dir"], "empty_file": files["empty"]}
        f = other.get(k, npz.get(k))
        add(f"info {k}", "info", f, "--json")
        for fmt, sfx in (("arkit", "csv"), ("glb", "glb"), ("bvh", "bvh"), ("vrma", "vrma")):
            add(f"export {fmt} {k}", "export", fmt, f, "--out", out / f"e_{k}.{sfx}")
        add(f"retarget {k}", "retarget", f, "--avatar", asset(AVATAR), "--out", out / f"r_{k}.vrm")
        add(f"livelink {k}", "livelink", f, "--to", "127.0.0.1:9")
        add(f"vmc {k}", "vmc", f, "--to", "127.0.0.1:9")
    add("livelink of a sequence with no face", "livelink", npz["no_face"], "--to", "127.0.0.1:9")
    for to in ("", "11111", "host:", ":11111", "127.0.0.1:70000", "127.0.0.1:-1", "no.such.host.invalid:11111"):
        add(f"livelink --to {to!r}", "livelink", base, "--to", to)
    add("livelink --loops 0", "livelink", base, "--to", "127.0.0.1:9", "--loops", "0")
    for to in ("", "39539", "host:", "127.0.0.1:70000", "no.such.host.invalid:39539", "[::1:9", "a:" + "9" * 5000):
        add(f"vmc --to {to[:20]!r}", "vmc", base, "--to", to)
        add(f"live --vmc {to[:20]!r}", "live", d0, "--no-browser", "--vmc", to)
    add("vmc a folder without a sequence", "vmc", files["dir"], "--to", "127.0.0.1:9")
    add("export fbx --out .glb", "export", "fbx", base, "--out", out / "f.glb")
    add("export fbx --units km", "export", "fbx", base, "--out", out / "f.fbx", "--units", "km")
    add("export glb --units cm", "export", "glb", base, "--out", out / "f2.glb", "--units", "cm")
    for k in ("missing", "dir", "empty", "random", "text", "png", "wav"):
        add(f"live source {k}", "live", files[k], "--no-browser")
    for src in ("rtsp://example.com/cam", "concat:a.mp4|b.mp4", "file:/etc/passwd", "9999", "-1"):
        add(f"live source {src}", "live", src, "--no-browser")
    add("live --livelink nohost", "live", d0, "--no-browser", "--livelink", "nohost")
    add("live --trackers 0", "live", d0, "--no-browser", "--trackers", "0")
    add("live --max-seconds 0", "live", d0, "--no-browser", "--max-seconds", "0")
    add("live --port 70000", "live", d0, "--no-browser", "--port", "70000")
    add("livelink --subject ''", "livelink", base, "--to", "127.0.0.1:9", "--subject", "")
    for k in ("missing", "dir", "empty", "random", "text", "png", "wav"):
        add(f"retarget --avatar {k}", "retarget", base, "--avatar", files[k], "--out", out / f"ra_{k}.glb")
    add("retarget .vrm out of a glTF avatar", "retarget", base, "--avatar", npz_glb(d, base), "--out", out / "r.vrm")
    add("retarget a folder without a sequence", "retarget", files["dir"], "--avatar", asset(AVATAR), "--out",
        out / "r2.vrm")  # fmt: skip
    add("retarget no --avatar", "retarget", base, "--out", out / "r3.vrm")

    add("export bvh of a face-only sequence", "export", "bvh", npz["face_only"], "--out", out / "x.bvh")
    add("export bvh with no full body", "export", "bvh", npz["body_all_nan"], "--out", out / "y.bvh")
    add("export arkit with no face", "export", "arkit", npz["no_face"], "--out", out / "z.csv")
    add("export glb with no face", "export", "glb", npz["no_face"], "--out", out / "z.glb")
    for v in NUM_BAD + ["1000000"]:
        add(f"export bvh --fps {v}", "export", "bvh", base, "--out", out / "f.bvh", "--fps", v)
    add("export arkit --fps", "export", "arkit", base, "--out", out / "f.csv", "--fps", "30")
    add("export --out is a folder", "export", "arkit", base, "--out", files["dir"])
    add("export --out in /proc", "export", "glb", base, "--out", "/proc/anima/x.glb")
    add("export bogus format", "export", "obj", base, "--out", out / "f.obj")

    for k in ("missing", "unicode_missing", "dir", "empty", "random", "text", "png", "novideo_audio", "cut"):
        add(f"audio features {k}", "audio", "features", files[k], "--out", out / f"a_{k}.npz")
    for opt, vals in (("--fps", NUM_BAD + ["1000000"]), ("--frames", ["0", "-1", "abc", "1.5", "100000000"])):
        for v in vals:
            add(f"audio {opt} {v}", "audio", "features", files["wav"], opt, v, "--out", out / "a.npz")
    add("audio --out is a folder", "audio", "features", files["wav"], "--out", files["dir"])

    for k in ("missing", "text", "empty", "random", "png"):
        add(f"dataset build only {k}", "dataset", "build", files[k], "--out", out / f"ds_{k}", "--quiet")
    add("dataset build nothing found", "dataset", "build", str(d / "nothing" / "*.mp4"), "--out", out / "ds_n")
    add("dataset build --out is a file", "dataset", "build", d0, "--out", files["text"])
    add("dataset build of another schema", "dataset", "build", d0, "--out", ds["old_version"])
    add("dataset build bad manifest", "dataset", "build", d0, "--out", ds["bad_json"])
    add("dataset build min > max", "dataset", "build", d0, "--out", out / "ds_mm", "--min-len", "9", "--max-len", "3")
    for opt in ("--min-len", "--max-len", "--max-yaw", "--max-fit-nme", "--descriptions", "--workers", "--max-frames"):
        for v in ("-1", "nan", "abc"):
            add(f"dataset build {opt} {v}", "dataset", "build", d0, "--out", out / "ds_o", opt, v)
    for k, p in ann.items():
        add(f"dataset build --annotations {k}", "dataset", "build", d0, "--out", out / f"ds_a_{k}", "--annotations", p)
    for k, p in ds.items():
        if k not in ("corrupt_shard", "no_windows"):
            add(f"dataset report {k}", "dataset", "report", p)
    add("dataset report --sheets -1", "dataset", "report", ds["empty_dir"], "--sheets", "-1")

    for k, p in ds.items():
        add(f"gesture --db {k}", "gesture", speech, "--db", p, "--out", out / f"g_{k}", "--no-render")
        add(f"train gesture --db {k}", "train", "gesture", "--db", p, "--out", out / f"t_{k}.pt", "--quiet")
        add(
            f"train gesture generator --db {k}",
            "train",
            "gesture",
            "--db",
            p,
            "--model",
            "generator",
            "--out",
            out / f"tg_{k}.pt",
            "--quiet",
        )
        add(f"eval gesture --db {k}", "eval", "gesture", "--db", p, "--json")
        add(f"eval all --db {k}", "eval", "all", "--db", p, "--out", out / f"ea_{k}", "--json")
        add(f"train text2face {k}", "train", "text2face", p, "--out", out / f"tt_{k}", "--quiet")
        add(f"eval text2face {k}", "eval", "text2face", p, "--work", out / f"et_{k}", "--json")
    for k in ("missing", "unicode_missing", "dir", "empty", "random", "text", "png", "novideo_audio", "short_wav"):
        add(f"gesture speech {k}", "gesture", files[k], "--db", ds["corrupt_shard"], "--out", out / f"gs_{k}")
    for k, p in ck.items():
        add(f"gesture --generator {k}", "gesture", speech, "--generator", p, "--out", out / f"gg_{k}", "--no-render")
        add(
            f"gesture --refiner {k}",
            "gesture",
            speech,
            "--db",
            ds["corrupt_shard"],
            "--refiner",
            p,
            "--out",
            out / f"gr_{k}",
        )
        add(f"text2face --checkpoint {k}", "text2face", "a woman smiles", "--checkpoint", p, "--out", out / f"tc_{k}")
        add(f"eval pose --model {k}", "eval", "pose", "--model", p, "--json")
        add(f"capture lifter {k}", "capture", pats, "--out", out / f"cl_{k}", "--body-3d", "lifter", "--pose-model", p)
    for opt, v in (
        ("--k", "-1"),
        ("--k", "abc"),
        ("--init", "bogus"),
        ("--control", "elbow_twist>=p50"),
        ("--control", "left_wrist_height>>p50"),
        ("--control", "left_wrist_height>=p50@5-1s"),
        ("--keyword", "yes at 3s"),
        ("--keyword", "yes@2-1s"),
        ("--keyword-db", "yes"),
        ("--keyword-db", f"yes={d / 'nope'}"),
    ):
        add(f"gesture {opt} {v}", "gesture", speech, "--db", ds["corrupt_shard"], opt, v, "--out", out / "go")
    add("gesture both --db and --generator", "gesture", speech, "--db", ds["corrupt_shard"], "--generator", speech,
        "--out", out / "gn")  # fmt: skip
    add(
        "gesture --generator with --control",
        "gesture",
        speech,
        "--generator",
        ck["random"],
        "--control",
        "left_wrist_height>=p50",
        "--out",
        out / "gc",
    )
    add("gesture --out is a file", "gesture", speech, "--db", ds["corrupt_shard"], "--out", files["text"])
    add(
        "train gesture --model bogus",
        "train",
        "gesture",
        "--db",
        ds["corrupt_shard"],
        "--model",
        "bogus",
        "--out",
        out / "tb.pt",
    )
    add("train gesture --steps 0", "train", "gesture", "--db", ds["corrupt_shard"], "--steps", "0", "--out", out / "t0")
    add("train gesture --out is a folder", "train", "gesture", "--db", ds["corrupt_shard"], "--out", files["dir"])

    for prompt in ("", "   ", "\n\t"):
        add(f"text2face prompt {prompt!r}", "text2face", prompt, "--out", out / "tp", "--no-video")
    for opt, vals in (("--length", ["0", "-1", "abc", "5", "100000"]), ("--seconds", NUM_BAD), ("--seed", ["abc"])):
        for v in vals:
            add(f"text2face {opt} {v}", "text2face", "a woman smiles", opt, v, "--out", out / "tl", "--no-video")
    add("text2face --out is a file", "text2face", "a woman smiles", "--out", files["text"])
    for k in ("missing", "unicode_missing", "dir", "empty", "random", "text", "cut", "png", "wav", "noface"):
        add(f"library build {k}", "library", "build", files[k], "--out", out / f"lb_{k}", "--quiet")
    add("library build --out is a file", "library", "build", pats, "--out", files["text"], "--quiet")
    add("library build --out a user's npz", "library", "build", pats, "--out", npz["zeros"], "--quiet")
    add("library build --max-frames 0", "library", "build", pats, "--out", out / "lb_mf", "--max-frames", "0")
    for k in ("missing", "dir", "text"):
        add(f"gesture --library {k}", "gesture", speech, "--library", files[k], "--out", out / "gl", "--no-render")
        add(f"text2face --library {k}", "text2face", "a woman smiles", "--library", files[k], "--out", out / "tlb")
    add("gesture --library and --db", "gesture", speech, "--library", files["dir"], "--db", ds["corrupt_shard"],
        "--out", out / "gld")  # fmt: skip
    for opt, vals in (
        ("--steps", ["0", "-1", "abc"]),
        ("--lr", ["0", "nan", "-1"]),
        ("--tf-drop", ["1.5", "-0.1"]),
        ("--kind", ["bogus"]),
        ("--batch", ["0"]),
        ("--codebook", ["1"]),
    ):
        for v in vals:
            add(f"train text2face {opt} {v}", "train", "text2face", ds["corrupt_shard"], opt, v, "--quiet")
    for opt, v in (("--steps", "0"), ("--batch", "1"), ("--width", "2"), ("--steps", "nan")):
        add(f"train pose {opt} {v}", "train", "pose", opt, v, "--out", out / "p.pt", "--quiet")

    target = str(asset("styletalk-samples/samples/source_video/video/Obama_clip1.mp4"))
    for k in ("missing", "unicode_missing", "dir", "empty", "random", "text", "png", "cut"):
        add(f"reenact actor {k}", "reenact", "--actor", files[k], "--target", target, "--out", out / "r.mp4")
        add(f"reenact target {k}", "reenact", "--actor", d0, "--target", files[k], "--out", out / "r.mp4")
    for opt, vals in (
        ("--n", ["0", "-1", "abc"]),
        ("--a", ["0", "1", "nan", "2"]),
        ("--smooth", ["-1", "abc"]),
        ("--max-seconds", ["0", "nan"]),
    ):
        for v in vals:
            add(f"reenact {opt} {v}", "reenact", "--actor", d0, "--target", target, "--out", out / "r.mp4", opt, v)
    add("reenact no --out", "reenact", "--actor", d0, "--target", target)
    add("reenact neither actor nor live", "reenact", "--target", target, "--out", out / "r.mp4")
    add("reenact --out is a folder", "reenact", "--actor", d0, "--target", target, "--out", files["dir"])
    add(
        "reenact --db is a folder",
        "reenact",
        "--actor",
        d0,
        "--target",
        target,
        "--out",
        out / "r.mp4",
        "--db",
        files["dir"],
    )
    add("reenact actor and live", "reenact", "--actor", d0, "--live", "0", "--target", target, "--out", out / "r.mp4")
    for src in (
        f"concat:{d0}|{d0}",
        f"subfile,,start,0,end,100,,:{d0}",
        f"file://{d0}",
        "http://127.0.0.1:9/x.mp4",
        "rtsp://127.0.0.1:9/x",
        "https://example.com/a.mp4",
        str(d / "frame%03d.png"),
        "tcp://127.0.0.1:9",
        "udp://127.0.0.1:9",
        f"pipe:{d0}",
        str(files["missing"]),
        str(files["text"]),
        "data:text/plain,hi",
        "12345",
    ):
        add(f"reenact --live {src[:40]}", "reenact", "--live", src, "--target", target, "--max-seconds", "1")

    add("eval body matches nothing", "eval", "body", "no-such-folder/*.mp4", "--json")
    add("eval stability missing clip", "eval", "stability", files["missing"], "--json")
    add("eval stability text clip", "eval", "stability", files["text"], "--json")
    add("eval pose --ablation-steps 0", "eval", "pose", "--ablation", out / "abl", "--ablation-steps", "0")
    add("eval text2face --reps 0", "eval", "text2face", ds["corrupt_shard"], "--reps", "0")
    for grid in ("0,250", "250,abc", ","):
        add(f"eval text2face --step-grid {grid}", "eval", "text2face", ds["corrupt_shard"], "--step-grid", grid)
    add("eval gesture --refiner-folds -1", "eval", "gesture", "--db", ds["corrupt_shard"], "--refiner-folds", "-1")
    add("eval reenact --out is a file", "eval", "reenact", "--out", files["text"])
    add("eval all --out is a file", "eval", "all", "--db", ds["empty_dir"], "--out", files["text"])

    for k in ("missing", "dir", "text", "empty"):
        add(f"facemodel import {k}", "facemodel", "import", files[k], "--out", out / "fm.npz")
    add("facemodel import --out is a folder", "facemodel", "import", files["dir"], "--out", files["dir"])
    for k in ("missing", "text", "empty", "random", "dir"):
        add(
            f"facemodel correspondence image {k}",
            "facemodel",
            "correspondence",
            "--images",
            files[k],
            "--out",
            out / "corr.npz",
        )
    for v in ("0", "-1", "nan", "abc"):
        add(f"facemodel landmarks68 --radius {v}", "facemodel", "landmarks68", "--radius", v, "--out", out / "l.json")

    # anima view: every crafted sequence in a result folder, every broken dataset, and bad places to write to
    for k in seq_bad:
        f = d / "view_in" / k
        f.mkdir(parents=True, exist_ok=True)
        (f / "capture.npz").write_bytes(Path(npz[k]).read_bytes())
        add(f"view capture.npz {k}", "view", f, "--static", out / f"v_{k}")
    for k, f in ds.items():
        add(f"view dataset {k}", "view", f, "--static", out / f"vd_{k}")
    for k in ("missing", "text", "empty", "dir"):
        add(f"view folder {k}", "view", files[k], "--no-browser")
    add("view --static is a file", "view", d / "view_in" / seq_bad[0], "--static", files["text"])
    for v in ("0", "-1", "65536", "abc"):
        add(f"view --port {v}", "view", files["dir"], "--port", v, "--no-browser")
    foreign = d / "studio_foreign"
    foreign.mkdir(exist_ok=True)
    (foreign / "notes.txt").write_text("a user's file")
    for v in ("-1", "65536", "abc"):
        add(f"studio --port {v}", "studio", "--root", d / "studio_root", "--port", v, "--no-browser")
    for v in ("0", "-5", "abc"):
        add(f"studio --max-upload-mb {v}", "studio", "--root", d / "studio_root", "--max-upload-mb", v, "--no-browser")
    add("studio --root is a file", "studio", "--root", files["text"], "--no-browser")
    add("studio --root holds a user's files", "studio", "--root", foreign, "--no-browser")

    for name, argv in _red_team(d, files, npz, base, ck, ds):
        add(name, *argv)
    add("unknown command", "fly")
    add("unknown option", "info", "--frobnicate")
    add("eval unknown", "eval", "everything")
    add("train unknown", "train", "dragon")
    return c


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    d = tmp_path_factory.mktemp("bad inputs ✓")
    cs = cases(d)
    before = _snapshot(d)
    lines = "".join(
        json.dumps({"id": i, "argv": argv, "env": env, "timeout": 120}) + "\n" for i, (_, argv, env) in enumerate(cs)
    )
    half = [lines.splitlines(keepends=True)[k::2] for k in range(2)]  # two runners for two cores
    procs = [
        subprocess.Popen(
            [sys.executable, str(REPO / "tests" / "forkrun.py")],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            cwd=d,
        )
        for _ in half
    ]
    # both runners at once (communicating with one, then the other, would feed the second nothing until the first
    # was done: the two halves ran one after the other)
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(len(procs)) as pool:
        outs = list(pool.map(lambda ph: ph[0].communicate("".join(ph[1]), timeout=3000)[0], zip(procs, half)))
    res = {r["id"]: r for o in outs for r in map(json.loads, o.splitlines())}
    assert not (d / "pwned").exists(), "a crafted checkpoint ran code"
    _touched.update(before=before, after=_snapshot(d))
    if os.environ.get("ANIMA_BAD_INPUT_LOG"):
        Path(os.environ["ANIMA_BAD_INPUT_LOG"]).write_text(
            json.dumps([{"name": n, **res[i]} for i, (n, _, _) in enumerate(cs)], indent=1)
        )
    return [(name, argv, res[i]) for i, (name, argv, _) in enumerate(cs)]


_touched: dict = {}


def _snapshot(d: Path) -> dict:
    """What the user owns in the matrix's folder: every file of the user's folders (content hash, mode) and
    what the special files are."""
    import hashlib
    import stat

    snap = {}
    for folder in (d / "user", d / "inputs", d / "results"):
        for p in sorted(folder.rglob("*")):
            st = p.lstat()
            snap[str(p)] = (stat.S_IFMT(st.st_mode), hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "")
    for p in (d / "fifo", Path("/dev/full")):
        if os.path.lexists(p):
            snap[str(p)] = (stat.S_IFMT(p.lstat().st_mode), "")
    return snap


def test_red_team_outputs_touch_no_user_file(results):
    """--out at a user's folder, at the folder holding the inputs, at an input, at a special file: refused for
    that reason, and every user file and special file is as it was."""
    own = [(n, r) for n, _, r in results if n.startswith("own ")]
    assert len(own) >= 30
    wrong = [f"{n}: {r['stderr'][-200:]!r}" for n, r in own if not any(w in r["stderr"] for w in OWNERSHIP)]
    assert not wrong, wrong
    assert _touched["after"] == _touched["before"]


def test_red_team_memory_and_nan_cases_are_refused_quickly(results):
    """The memory bombs (a stride-0 checkpoint tensor, a zip bomb, a 0.001-fps export, a config of a huge model)
    and NaN inputs are refused before allocating: each case is seconds, not the minutes of a swapping machine,
    and a non-Ray --address is refused within 10 s."""
    slow = [(n, r["seconds"]) for n, _, r in results if n.split()[0] in ("mem", "nan", "exit1") and r["seconds"] > 20]
    assert not slow, slow
    addr = next(r for n, _, r in results if "--address" in n)
    assert addr["rc"] == 2 and addr["seconds"] < 10, addr


def test_at_least_300_cases_over_every_command(results):
    from anima.cli.main import build_parser

    sub = next(a for a in build_parser()._actions if a.__class__.__name__ == "_SubParsersAction")
    assert len(results) >= 300
    assert set(sub.choices) <= {argv[0] for _, argv, _ in results}, set(sub.choices) - {a[0] for _, a, _ in results}


def test_every_bad_input_is_one_line_and_exit_2_3_or_4(results):
    bad = []
    for name, _argv, r in results:
        err = r["stderr"]
        one_line = err.count("\n") == 1 and err.startswith("anima: error:") and "Traceback" not in err
        ok = r["rc"] in (2, 3, 4) and one_line
        if not ok:
            bad.append(f"{name}: rc {r['rc']}, stderr {err[-300:]!r}, stdout {r['stdout'][-200:]!r}")
    assert not bad, f"{len(bad)} of {len(results)} cases broke the contract:\n" + "\n".join(bad)


# --- What a result folder and a single-file export may replace (ownership on write) ---


def _refused(r, *words):
    """A one-line refusal (exit 2) naming ``words``."""
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and r.stderr.startswith("anima: error:"), r.stderr
    assert all(w in r.stderr for w in words), r.stderr


def test_a_rerun_keeps_a_file_the_user_edited_in_its_result(tmp_path, cli):
    """Edit arkit.csv inside a capture result, run the same capture into it again: refused, naming the file;
    the edit kept. Unedited, the rerun replaces anima's own files."""
    clip, res = asset(D0), tmp_path / "res"
    argv = ("capture", clip, "--out", res, "--face-only", "--max-frames", "20", "--no-render", "--quiet")
    assert cli(*argv).returncode == 0
    assert cli(*argv).returncode == 0  # anima's own, unchanged: replaced
    csv = res / "arkit.csv"
    edited = csv.read_text() + "my,own,line\n"
    csv.write_text(edited)
    before = {p.name: p.read_bytes() for p in res.iterdir() if p.is_file()}
    _refused(cli(*argv), "arkit.csv", "changed since anima wrote it")
    assert {p.name: p.read_bytes() for p in res.iterdir() if p.is_file()} == before


def test_a_copied_marker_does_not_make_a_users_folder_animas(tmp_path, cli):
    """``cp -a res/. proj/`` into a folder with the user's own files: the marker came along, but the folder
    holds files anima never wrote there, so a capture into it is refused and the user's files stay."""
    import shutil

    res, proj = tmp_path / "res", tmp_path / "proj"
    argv = ("--face-only", "--max-frames", "20", "--no-render", "--quiet")
    assert cli("capture", asset(D0), "--out", res, *argv).returncode == 0
    proj.mkdir()
    (proj / "capture.npz").write_bytes(b"the user's own capture")
    (proj / "notes.txt").write_text("my notes\n")
    for f in res.iterdir():
        if f.name not in ("capture.npz", "manifest.json"):
            shutil.copy2(f, proj / f.name)
    (proj / "manifest.json").write_text('{"mine": true}\n')
    before = {p.name: p.read_bytes() for p in proj.iterdir()}
    _refused(cli("capture", asset(D0), "--out", proj, *argv), "did not write", "notes.txt")
    assert {p.name: p.read_bytes() for p in proj.iterdir()} == before


def test_an_export_keeps_a_csv_the_user_appended_to(tmp_path, cli):
    """``export arkit --out mine.csv`` over a CSV anima wrote that has the user's lines appended: refused (the
    whole file is checked against the record beside it, not its header); unchanged, it is replaced; the record
    does not enter the CSV, so Live Link readers read it as before."""
    from anima.io.arkit import read_live_link_csv

    seq = _sequence(tmp_path / "take.npz")
    out = tmp_path / "mine.csv"
    assert cli("export", "arkit", seq, "--out", out).returncode == 0
    assert cli("export", "arkit", seq, "--out", out).returncode == 0
    read_live_link_csv(out)
    out.write_text(out.read_text() + "00:00:09:00.000,1\n")
    edited = out.read_bytes()
    _refused(cli("export", "arkit", seq, "--out", out), "changed since anima wrote it")
    assert out.read_bytes() == edited


def test_a_neutral_take_that_is_not_at_rest_is_refused(tmp_path, cli):
    """``capture --neutral`` with the same actor's happy take (CREMA-D 1001: a smile held all clip): refused in
    one line naming the strong channels, before the capture and before --out is made; his neutral take is
    taken (its rest named in the sequence)."""
    argv = ("--face-only", "--no-render", "--quiet")  # no --max-frames: it would cut the neutral take too
    r = cli("capture", asset(D0), "--out", tmp_path / "a", "--neutral",
            asset("emotion-clips/crema-d/1001_DFA_HAP_XX.flv"), *argv)  # fmt: skip
    _refused(r, "is not a face at rest", "mouthSmile")
    assert not (tmp_path / "a").exists()
    r = cli("capture", asset(D0), "--out", tmp_path / "b", "--neutral",
            asset("emotion-clips/crema-d/1001_DFA_NEU_XX.flv"), *argv)  # fmt: skip
    assert r.returncode == 0, r.stderr


# --- Bounds on what a prompt or a speech file implies; nested JSON ---


def _measured(argv: list, timeout: float = 120) -> tuple[int, str, float, float]:
    """Run ``anima ARGV`` in a new interpreter: its exit code, stderr, seconds and peak memory (GB, the
    process's own maximum resident set, from wait4)."""
    import tempfile
    import threading
    import time

    t0 = time.perf_counter()
    with tempfile.TemporaryFile("w+") as fh:
        p = subprocess.Popen([sys.executable, "-m", "anima", *map(str, argv)], stdout=subprocess.DEVNULL, stderr=fh)
        killer = threading.Timer(timeout, p.kill)
        killer.start()
        try:
            _, status, usage = os.wait4(p.pid, 0)
        finally:
            killer.cancel()
        p.returncode = os.waitstatus_to_exitcode(status)  # (reaped here: Popen must not wait for it again)
        fh.seek(0)
        stderr = fh.read()
    return p.returncode, stderr, time.perf_counter() - t0, usage.ru_maxrss / 2**20  # ru_maxrss: KB on Linux


def _one_line(rc: int, stderr: str, *words) -> None:
    assert rc in (2, 3, 4) and stderr.count("\n") == 1 and stderr.startswith("anima: error:"), (rc, stderr[-2000:])
    assert "Traceback" not in stderr and all(w in stderr for w in words), stderr


def test_a_prompt_past_its_limits_is_refused_within_a_minute(tmp_path):
    """The red team's 55,000-character prompt (5,000 blinks: 128,778 frames, over two minutes and 5.8 GB): refused
    in one line (exit 2) within 60 s and 2 GB, before --out is made; so are 150 events in few characters, and events
    that need more than the timeline method's 10 minutes; --help states the limits."""
    from anima.text2face.prompt import MAX_PROMPT_CHARS, MAX_PROMPT_EVENTS
    from anima.text2face.run import MAX_TIMELINE_FRAMES

    out = tmp_path / "t2f"
    blinks = " then ".join(["blink"] * 5000)
    rc, err, seconds, gb = _measured(["text2face", blinks, "--out", out, "--no-video"])
    _one_line(rc, err, f"{MAX_PROMPT_CHARS:,}")
    assert rc == 2 and seconds < 60 and gb < 2, (seconds, gb)
    many = " then ".join(["blink"] * 150)  # 1,144 characters
    rc, err, seconds, _ = _measured(["text2face", many, "--out", out, "--no-video"])
    _one_line(rc, err, f"at most {MAX_PROMPT_EVENTS}")
    long = ", then ".join(["smiles and blinks 50 times while nodding 50 times and shaking its head 50 times"] * 20)
    assert len(long) < MAX_PROMPT_CHARS
    rc, err, seconds, _ = _measured(["text2face", long, "--out", out, "--no-video"])
    _one_line(rc, err, f"at most {MAX_TIMELINE_FRAMES}")
    assert rc == 2 and seconds < 60 and not out.exists()
    r = subprocess.run([sys.executable, "-m", "anima", "text2face", "--help"], capture_output=True, text=True)
    text = " ".join(r.stdout.split())
    assert f"at most {MAX_PROMPT_CHARS:,} characters and {MAX_PROMPT_EVENTS} events" in text, r.stdout
    assert f"at most {MAX_TIMELINE_FRAMES} (10 min" in text, r.stdout


def test_a_speech_file_longer_than_the_command_takes_is_refused(tmp_path):
    """Speech past ``anima gesture``'s 10 minutes (and audio past ``anima audio features``' hour) is refused in
    one line (exit 2) after decoding no more than the limit, before --out is made; a file of the limit is taken.
    The files: real speech looped, and silence."""
    from anima.audio.features import MAX_AUDIO_S, read_audio
    from anima.gesture.run import MAX_SPEECH_S
    from anima.io.video import FFMPEG

    def make(path: Path, seconds: float, *src) -> Path:
        argv = [FFMPEG, "-hide_banner", "-nostdin", "-v", "error", "-y", *src, "-t", f"{seconds:g}"]
        subprocess.run([*argv, "-ac", "1", "-ar", "8000", "-c:a", "flac", str(path)], check=True)
        return path

    loop = ["-stream_loop", "-1", "-i", str(asset(SPEECH))]
    at_limit = make(tmp_path / "speech_10min.flac", MAX_SPEECH_S, *loop)
    over = make(tmp_path / "speech_over.flac", MAX_SPEECH_S + 2, *loop)
    out = tmp_path / "g"
    rc, err, seconds, gb = _measured(["gesture", over, "--out", out, "--no-render"])
    _one_line(rc, err, f"longer than {MAX_SPEECH_S:g} s")
    assert rc == 2 and seconds < 30 and gb < 2 and not out.exists(), (seconds, gb)
    hour = make(tmp_path / "hour.flac", MAX_AUDIO_S + 2, "-f", "lavfi", "-i", "anullsrc=r=8000:cl=mono")
    rc, err, seconds, gb = _measured(["audio", "features", hour, "--out", tmp_path / "hour.npz"])
    _one_line(rc, err, f"longer than {MAX_AUDIO_S:g} s")
    assert rc == 2 and seconds < 30 and gb < 2 and not (tmp_path / "hour.npz").exists(), (seconds, gb)
    x = read_audio(at_limit, max_s=MAX_SPEECH_S)  # ffmpeg decodes a little past the limit: a file of it is taken
    assert abs(len(x) / 16000 - MAX_SPEECH_S) < 0.05


def test_eval_all_resume_refuses_a_deeply_nested_results_file(tmp_path):
    """``anima eval all --resume`` into a folder whose results.json nests 100,000 lists (a RecursionError, exit 1,
    before): one line, exit 4, before the dataset is read or anything computed; as deep as anima's depth limit
    allows but no deeper, too."""
    from anima.errors import SchemaError
    from anima.eval.all import finished_rows
    from anima.io.outdir import OutputFolder
    from anima.io.validate import MAX_JSON_DEPTH

    out, db = tmp_path / "ea", tmp_path / "ds"
    db.mkdir()
    (db / "manifest.json").write_text('{"schema": "anima.dataset", "version": 1}')
    with OutputFolder(out, kind="eval_all") as od:
        Path(od.file("results.json")).write_text("[" * 100_000 + "]" * 100_000)
    before = (out / "results.json").read_bytes()
    rc, err, seconds, _ = _measured(["eval", "all", "--db", db, "--out", out, "--resume", "--only", "landmarks"])
    _one_line(rc, err, "results.json", "nested")
    assert rc == 4 and seconds < 30 and (out / "results.json").read_bytes() == before
    deep = "[" * (MAX_JSON_DEPTH + 1) + "]" * (MAX_JSON_DEPTH + 1)
    (out / "results.json").write_text(json.dumps({"provenance": {}, "rows": json.loads(deep)}))
    with pytest.raises(SchemaError, match="nested deeper"):
        finished_rows(out, {"commit": "a" * 40}, False)
    (out / "results.json").write_text("{not json")  # not JSON at all: its rows run again, as before
    assert finished_rows(out, {"commit": "a" * 40}, False) == ({}, 0.0)


# --- Addresses that cannot be sent to; view's source video; the view server's limits ---


def _anima_at(cwd: Path, *args, timeout: float = 120) -> subprocess.CompletedProcess:
    """``anima ARGS`` run in ``cwd`` (the folder matters to the cases below), as a user runs it."""
    r = subprocess.run(
        [sys.executable, "-m", "anima", *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=timeout
    )
    assert "Traceback" not in r.stderr, r.stderr[-3000:]
    return r


def _refused_one_line(r: subprocess.CompletedProcess, *words) -> None:
    assert r.returncode in (2, 3, 4), (r.returncode, r.stderr[-500:])
    assert r.stderr.count("\n") == 1 and r.stderr.startswith("anima: error:"), r.stderr
    assert all(w in r.stderr for w in words), r.stderr


def _udp_listener():
    """A UDP socket on 127.0.0.1 that records whatever reaches it (0.0.0.0 reaches it on Linux)."""
    import socket

    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(0.5)
    return rx


def _nothing_arrived(rx) -> bool:
    try:
        rx.recv(65536)
        return False
    except TimeoutError:
        return True


def _a_result(d: Path, source: dict | None = None) -> Path:
    """A result folder: a generated capture of 10 frames whose recorded source video is ``source``."""
    from anima.export.framing import generated_sequence
    from anima.io.sequence import write_sequence

    d.mkdir(parents=True, exist_ok=True)
    seq = generated_sequence(25.0, face=np.zeros((10, 56), np.float32))
    if source is not None:
        seq.meta["source"] = source
    write_sequence(seq, d / "capture.npz")
    return d


def test_vmc_and_livelink_refuse_addresses_that_cannot_be_sent_to(tmp_path):
    """``--to 0.0.0.0:P`` (the unspecified address: on Linux it lands on this machine), the broadcast address,
    ``[::]``, a multicast group, for every command that sends: one line, exit 2, before anything is read, tracked
    or sent (a listener on 127.0.0.1:P gets nothing; live loads no model)."""
    import time

    res = _a_result(tmp_path / "res")
    d0 = asset(D0)
    with _udp_listener() as rx:
        p = rx.getsockname()[1]
        cases = [
            ("vmc", res, "--to", f"0.0.0.0:{p}"),
            ("vmc", res, "--to", f"255.255.255.255:{p}"),
            ("vmc", res, "--to", f"[::]:{p}"),
            ("vmc", res, "--to", f"[::ffff:0.0.0.0]:{p}"),
            ("livelink", res / "capture.npz", "--to", f"0.0.0.0:{p}"),
            ("livelink", res / "capture.npz", "--to", f"224.0.0.1:{p}"),
            ("live", d0, "--no-browser", "--max-frames", "5", "--vmc", f"0.0.0.0:{p}"),
            ("live", d0, "--no-browser", "--max-frames", "5", "--livelink", f"255.255.255.255:{p}"),
            ("live", d0, "--no-browser", "--max-frames", "5", "--vmc", f"127.0.0.1:{p}", "--livelink", f"[::]:{p}"),
        ]
        for argv in cases:
            t0 = time.monotonic()
            r = _anima_at(tmp_path, *argv)
            _refused_one_line(r, "packets cannot be sent to", argv[-1].rsplit(":", 1)[0].strip("[]"))
            assert r.returncode == 2 and not r.stdout and time.monotonic() - t0 < 30, (argv, r.stdout[-300:])
        assert _nothing_arrived(rx)
    assert not (tmp_path / "take").exists()


def test_live_refuses_two_outputs_on_one_address_and_port(tmp_path):
    """``anima live --vmc H:P --livelink H:P`` (the same port, or a name of the same address): one receiver would
    get both streams; refused in one line, exit 2, before tracking."""
    d0 = asset(D0)
    with _udp_listener() as rx:
        p = rx.getsockname()[1]
        for vmc, ll in ((f"127.0.0.1:{p}", f"127.0.0.1:{p}"), (f"localhost:{p}", f"127.0.0.1:{p}")):
            r = _anima_at(tmp_path, "live", d0, "--no-browser", "--max-frames", "5", "--vmc", vmc, "--livelink", ll)
            _refused_one_line(r, "--livelink and --vmc both send to", f"127.0.0.1:{p}")
            assert r.returncode == 2 and not r.stdout
        assert _nothing_arrived(rx)


def test_view_never_takes_the_source_video_from_the_current_folder(tmp_path):
    """A capture of ``clip.mp4`` run in one folder, viewed from another folder that holds another ``clip.mp4``: the
    page's source video is the captured one (the capture records where it is), never the current folder's; a
    result whose recorded source is relative (an older capture) looks it up in the result folder only: not there,
    the page has no source video and a note says so."""
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    b.mkdir()
    (a / "clip.mp4").write_bytes(asset(D0).read_bytes())
    (b / "clip.mp4").write_bytes(asset(PATS).read_bytes())  # another person's clip under the same name
    r = _anima_at(a, "capture", "clip.mp4", "--out", tmp_path / "cap", "--max-frames", "3", "--face-only",
                  "--no-render", "--quiet")  # fmt: skip
    assert r.returncode == 0, r.stderr[-2000:]
    r = _anima_at(b, "view", tmp_path / "cap", "--static", tmp_path / "page")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "page" / "source.mp4").read_bytes() == (a / "clip.mp4").read_bytes()
    # an older result: the source recorded as typed, relative ("clip.mp4")
    from anima.io.video import probe_video

    old = _a_result(tmp_path / "old", {**probe_video(a / "clip.mp4").as_dict(), "path": "clip.mp4"})
    r = _anima_at(b, "view", old, "--static", tmp_path / "page_old")
    assert r.returncode == 0, r.stderr
    assert not (tmp_path / "page_old" / "source.mp4").exists()
    said = [x for x in r.stderr.splitlines() if "no source video" in x]
    assert len(said) == 1 and said[0].startswith("anima: note:") and "clip.mp4" in said[0], r.stderr
    assert "source video" not in (tmp_path / "page_old" / "view-data.js").read_text().replace("no source video", "")
    # relative to the result: a source inside the result folder is found from anywhere
    (old / "clip.mp4").write_bytes((a / "clip.mp4").read_bytes())
    r = _anima_at(b, "view", old, "--static", tmp_path / "page_inside")
    assert r.returncode == 0 and "no source video" not in r.stderr, r.stderr
    assert (tmp_path / "page_inside" / "source.mp4").read_bytes() == (a / "clip.mp4").read_bytes()


def test_a_crafted_result_cannot_copy_a_local_video_into_its_page(tmp_path):
    """A result whose recorded source points at a video it did not capture (an absolute path to another video, a
    ``..`` out of the result, a symlink in it) gets no source video, said in one note: ``view --static`` copies
    nothing of it, and ``anima view`` does not serve it."""
    from anima.io.video import probe_video

    private = tmp_path / "private.mp4"
    private.write_bytes(asset(PATS).read_bytes())
    captured = probe_video(asset(D0)).as_dict()  # what the crafted result claims to have tracked
    crafted = {
        "absolute, another video": {**captured, "path": str(private)},
        "absolute, no record of it": {"path": str(private), "codec": "h264"},
        "relative, out of the result": {**probe_video(private).as_dict(), "path": "../private.mp4"},
        "a symlink in the result": {**probe_video(private).as_dict(), "path": "clip.mp4"},
        "a device": {**captured, "path": "/dev/zero"},
    }
    secret = private.read_bytes()[-4096:]
    for k, (name, source) in enumerate(crafted.items()):
        res = _a_result(tmp_path / f"res{k}", source)
        (res / "clip.mp4").symlink_to(private)
        page = tmp_path / f"page{k}"
        r = _anima_at(tmp_path, "view", res, "--static", page)
        assert r.returncode == 0 and "Traceback" not in r.stderr, (name, r.stderr)
        said = [x for x in r.stderr.splitlines() if "no source video" in x]
        assert len(said) == 1 and said[0].startswith("anima: note:"), (name, r.stderr)
        assert not list(page.glob("source*")), name
        assert not any(secret in p.read_bytes() for p in page.iterdir() if p.is_file()), name
        assert "source.mp4" not in (page / "view-data.js").read_text(), name
    # served: the page lists no source video, and there is none to ask for
    from browser import served

    with served(tmp_path / "res0") as (url, _):
        import urllib.error
        import urllib.request

        with pytest.raises(urllib.error.HTTPError) as e:
            urllib.request.urlopen(url.replace("index.html", "source.mp4"), timeout=10)
        assert e.value.code == 404
        assert b"source.mp4" not in urllib.request.urlopen(url.replace("index.html", "view-data.js"), timeout=10).read()
    # the video the capture did track, where it recorded it: taken
    real = tmp_path / "clip.mp4"
    real.write_bytes(asset(D0).read_bytes())
    r = _anima_at(tmp_path, "view", _a_result(tmp_path / "genuine", {**captured, "path": str(real)}), "--static",
                  tmp_path / "page_genuine")  # fmt: skip
    assert r.returncode == 0 and "no source video" not in r.stderr, r.stderr
    assert (tmp_path / "page_genuine" / "source.mp4").read_bytes() == real.read_bytes()


def _port_token(url: str) -> tuple[int, str]:
    import re

    port, token = re.search(r":(\d+)/([A-Za-z0-9_-]+)/index\.html", url).groups()
    return int(port), token


def test_view_server_cuts_a_request_that_trickles_in_but_not_a_slow_download(tmp_path):
    """A client that sends its request a byte every half second (each read well within the idle timeout) is cut
    off at the request time limit, not held for ever; meanwhile a client reading a 3 MB video slowly, for longer
    than that limit, gets every byte."""
    import contextlib
    import socket
    import threading
    import time

    from browser import served

    from anima.io.video import probe_video
    from anima.view.serve import IDLE_TIMEOUT_S, REQUEST_S

    video = asset(D0).read_bytes()  # the result's own source video, beside it
    res = _a_result(tmp_path / "res", {**probe_video(asset(D0)).as_dict(), "path": "clip.mp4"})
    (res / "clip.mp4").write_bytes(video)
    with served(res) as (url, _):
        port, tok = _port_token(url)
        got: dict = {}

        def slow_download():
            s = socket.socket()
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8192)
            s.connect(("127.0.0.1", port))
            s.settimeout(30)
            s.sendall(f"GET /{tok}/source.mp4 HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n".encode())
            t0, data = time.monotonic(), b""
            while chunk := s.recv(16384):
                data += chunk
                time.sleep(0.05)  # about 300 kB/s: longer than the request time limit for the whole video
            got.update(seconds=time.monotonic() - t0, body=data.partition(b"\r\n\r\n")[2], head=data[:20])
            s.close()

        reader = threading.Thread(target=slow_download, daemon=True)
        reader.start()
        request = f"GET /{tok}/index.html HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nX-Slow: {'a' * 200}".encode()
        with socket.create_connection(("127.0.0.1", port), timeout=IDLE_TIMEOUT_S + 10) as s:
            t0, cut = time.monotonic(), None
            for byte in request:
                try:
                    s.sendall(bytes([byte]))
                    s.setblocking(False)
                    with contextlib.suppress(BlockingIOError):
                        if s.recv(1) == b"":
                            cut = time.monotonic() - t0
                            break
                    s.setblocking(True)
                except (ConnectionResetError, BrokenPipeError):
                    cut = time.monotonic() - t0
                    break
                time.sleep(0.5)
        assert cut is not None and REQUEST_S - 1 <= cut <= REQUEST_S + 3, cut
        reader.join(60)
        assert got["head"].startswith(b"HTTP/1.") and b" 200 " in got["head"], got.get("head")
        assert len(got["body"]) == len(video) and got["body"] == video
        assert got["seconds"] > REQUEST_S, got["seconds"]


def test_view_server_caps_its_connections_and_still_answers(tmp_path):
    """40 connections held open with a request that never ends (the cap is 32): the server stays within its cap
    (the connections that waited longest are closed) and still answers a normal request at once."""
    import socket
    import time

    from browser import served

    from anima.view.serve import MAX_CONNECTIONS

    with served(_a_result(tmp_path / "res")) as (url, _):
        port, tok = _port_token(url)
        held = []
        for _ in range(MAX_CONNECTIONS + 8):
            s = socket.create_connection(("127.0.0.1", port), timeout=10)
            s.sendall(b"GET /")
            held.append(s)
        time.sleep(0.5)
        t0 = time.monotonic()
        with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
            s.sendall(f"GET /{tok}/index.html HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\r\n".encode())
            data = b""
            while chunk := s.recv(65536):
                data += chunk
        assert b" 200 " in data.split(b"\r\n")[0] and b"viewer.js" in data, data[:200]
        assert time.monotonic() - t0 < 3
        time.sleep(0.3)
        closed = 0
        for s in held:
            s.setblocking(False)
            try:
                closed += s.recv(1) == b""
            except BlockingIOError:
                pass
            except OSError:
                closed += 1
            s.close()
        assert closed >= len(held) + 1 - MAX_CONNECTIONS, closed


# --- FBX: a misbehaving Blender, Ctrl-C, replacing its own FBX ---
def test_fbx_replaces_its_own_take_and_keeps_one_the_user_changed(tmp_path, cli):
    """``export fbx`` over the FBX it wrote: replaced (the record beside it matches the whole file). An FBX that
    changed since (re-saved by a DCC tool, here a byte appended): kept, exit 2, one line."""
    seq = _sequence(tmp_path / "motion.npz")
    out = tmp_path / "take.fbx"
    assert cli("export", "fbx", seq, "--out", out).returncode == 0
    first = out.read_bytes()
    r = cli("export", "fbx", seq, "--out", out)
    assert r.returncode == 0, r.stderr
    assert out.read_bytes()[:21] == first[:21]
    out.write_bytes(out.read_bytes() + b"\0")
    changed = out.read_bytes()
    r = cli("export", "fbx", seq, "--out", out)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "changed since anima wrote it" in r.stderr, r.stderr
    assert out.read_bytes() == changed


def test_fbx_refuses_a_blender_that_exits_without_writing_the_file(tmp_path, cli):
    """A ``blender`` on PATH that exits 0 and writes nothing, or one that fails with an error line: exit 3 (the
    external tool misbehaved), one line that says so with what Blender last said; no FBX, no temporary file."""
    seq = _sequence(tmp_path / "motion.npz")
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    fake = bin_dir / "blender"
    env = {"PATH": f"{bin_dir}{os.pathsep}{os.environ['PATH']}"}
    out = tmp_path / "take.fbx"
    for script, said, what in (
        ("echo 'fake blender: nothing exported here' >&2\nexit 0", "nothing exported here", "exited 0 without writing"),
        ("echo 'Blender 3.4.1'\necho 'Error: the export broke' >&2\nexit 1", "Error: the export broke", "exited 1"),
    ):
        fake.write_text(f"#!/bin/sh\n{script}\n")
        fake.chmod(0o755)
        r = cli("export", "fbx", seq, "--out", out, env=env)
        assert r.returncode == 3, r.stderr
        assert r.stderr.count("\n") == 1 and r.stderr.startswith(f"anima: error: Blender ({fake}) failed"), r.stderr
        assert what in r.stderr and said in r.stderr, r.stderr
        assert not out.exists() and not [f for f in tmp_path.iterdir() if ".anima-tmp-" in f.name]


def _blender_child(pid: int, timeout: float = 120) -> tuple[int, Path]:
    """The Blender that ``anima export fbx`` (process ``pid``) runs, and the temporary folder it works in."""
    import time

    deadline = time.time() + timeout
    while time.time() < deadline:
        try:
            kids = [int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
        except OSError:
            kids = []
        for c in kids:
            try:
                argv = Path(f"/proc/{c}/cmdline").read_bytes().decode().split("\0")
            except OSError:
                continue
            if any(a.endswith("fbx_from_gltf.py") for a in argv):
                return c, Path(argv[argv.index("--") + 1]).parent
        time.sleep(0.05)
    raise AssertionError("no Blender started")


def test_fbx_ctrl_c_kills_blender_and_leaves_nothing(tmp_path):
    """Ctrl-C while Blender exports: a terminal's (SIGINT to the whole process group) and SIGINT to ``anima``
    alone: each ends with exit 130 and the one interrupt line, Blender gone, no FBX, no temporary file or folder
    left. (A Ctrl-C that reaches Blender while ``anima`` ignores SIGINT, a job a script put in the background,
    races Blender's own end and is not tested.)"""
    import signal
    import time

    seq = _sequence(tmp_path / "motion.npz")
    out = tmp_path / "take.fbx"
    for to_group, ignored in ((True, False), (False, False)):
        p = subprocess.Popen(
            [sys.executable, "-m", "anima", "export", "fbx", str(seq), "--out", str(out)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN if ignored else signal.SIG_DFL),
        )  # fmt: skip
        try:
            blender, work = _blender_child(p.pid)
            time.sleep(0.5)  # in the middle of its export
            (os.killpg if to_group else os.kill)(p.pid, signal.SIGINT)
            _, err = p.communicate(timeout=120)
        finally:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
        case = f"to the group {to_group}, SIGINT ignored {ignored}"
        assert p.returncode == 130 and err == "anima: interrupted\n", (case, p.returncode, err)
        assert not Path(f"/proc/{blender}").exists(), case  # killed and reaped
        assert not out.exists() and not work.exists(), case
        assert not [f for f in tmp_path.iterdir() if ".anima-tmp-" in f.name], case
