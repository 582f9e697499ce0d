"""Which shared-data videos the built-in motion library may hold, and why (light: no I/O).

The library ships motion parameters only: per-frame ARKit expression weights and head rotation (text ->
face), the 55-joint upper body + hands and 28 speech features per frame (speech -> gesture). No pixels, no
audio samples, no identity shape. Even so, a video goes in only when its repository's licence lets derived
data be redistributed with an MIT project; the rest are listed with the reason they stay out.
"""

from __future__ import annotations

# (path under the data root, licence, included?) -- the first matching prefix decides
SOURCES: list[tuple[str, str, bool]] = [
    ("liveportrait-examples/", "MIT (KwaiVGI/LivePortrait)", True),
    ("styletalk-samples/", "MIT (FuxiVirtualHuman/styletalk)", True),
    ("videoretalking-examples/", "Apache-2.0 (OpenTalker/video-retalking)", True),
    ("talking-heads-misc/LatentSync/", "Apache-2.0 (bytedance/LatentSync)", True),
    ("talking-heads-misc/MimicTalk/", "MIT (yerfor/MimicTalk)", True),
    ("talking-heads-misc/Real3DPortrait/", "MIT (yerfor/Real3DPortrait)", True),
    ("talking-heads-misc/TPSMM/", "MIT (yoyo-nb/Thin-Plate-Spline-Motion-Model)", True),
    ("talking-heads-extra/RD_Radio", "none stated (tencent-ailab/V-Express): left out", False),
    ("talking-heads-extra/", "Apache-2.0 (tanshuai0219/EDTalk, Zejun-Yang/AniPortrait)", True),
    ("gesture-video/pats-crops/", "no licence, TV footage for research only: left out", False),
    ("gesture-video/tango-interviews/", "CC BY-NC 4.0: non-commercial, left out of an MIT package", False),
    ("emotion-clips/crema-d/", "ODbL (share-alike on derived databases): left out", False),
    ("emotion-clips/eamm-mead/", "MEAD terms (research use): left out", False),
    ("pose3d/", "research only: left out", False),
]


def licence_of(rel: str) -> tuple[str, bool]:
    """``(licence, included)`` of a video at ``rel`` (a path under the data root, '/'-separated)."""
    for prefix, lic, ok in SOURCES:
        if rel.startswith(prefix):
            return lic, ok
    return "not listed: left out", False
