"""The character's builds (``--body male|female|neutral``) side by side, each from the front and from the side, at
one scale with the feet on one line, and their chests close up below, drawn by anima's own rasterizer;
``docs/body_builds.png``, referenced from docs/rig.md.

    python tools/build_sheet.py [--out docs/body_builds.png] [--height 520]

Each build is the character in its coefficients (:func:`anima.facemodel.character.build_coeffs`), arms lowered
45 degrees (:func:`anima.export.vrm.character_avatar`'s A-pose) so the chest and hips show, in the vertices'
colours (:func:`anima.facemodel.character.vertex_colors`); the close-up of the chest in the rest (T-) pose.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from anima.export.vrm import character_avatar  # noqa: E402
from anima.facemodel.character import BUILDS, load_character, vertex_colors  # noqa: E402
from anima.render.avatar import draw_smooth, head_view  # noqa: E402

LABEL = 28
FONT, FONT_SCALE = cv2.FONT_HERSHEY_SIMPLEX, 0.55
BACKGROUND = (40, 40, 44)
TOP_M = 2.0
"""The picture's height, metres (feet at the bottom)."""
FRONT = np.eye(3)  # +z towards the viewer
SIDE = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])  # seen from its right: it faces right


CHEST_ZOOM = 2.0
"""The second row: the chest at this many times the first row's scale, centred at :data:`CHEST_AT` of the
build's height, in the T-pose (the arms out of the side view's way)."""
CHEST_AT = 0.70
CHEST_Z = 0.03
"""The close-up's centre this far in front of the body's axis (metres): the chest's profile in the side view."""


def sheet(height: int = 520) -> np.ndarray:
    """The sheet (RGB uint8): for each build of :data:`BUILDS` its front and its side view, labelled, the whole
    body above and the chest close up below."""
    ch = load_character()
    col, tris = vertex_colors(), ch.faces
    scale = height / TOP_M
    widths = {"front": int(1.4 * scale), "side": int(0.5 * scale)}
    cells = [(b, v) for b in BUILDS for v in ("front", "side")]
    rows = height // 2
    out = np.zeros((LABEL + height + rows, sum(widths[v] for _, v in cells), 3), np.uint8)
    out[:] = BACKGROUND
    x0 = 0
    for build, view in cells:
        A, T = character_avatar(build, "A")["vertices"], character_avatar(build, "T")["vertices"]
        w, R = widths[view], FRONT if view == "front" else SIDE
        for V, top, h, s, centre in ((A, LABEL, height, scale, np.array([0.0, TOP_M / 2, 0.0])),
                                     (T, LABEL + height, rows, scale * CHEST_ZOOM,
                                      np.array([0.0, CHEST_AT * T[:, 1].max(), CHEST_Z]))):  # fmt: skip
            img = np.zeros((h, w, 3), np.uint8)
            img[:] = BACKGROUND
            X = head_view(V, h, R, centre, s)
            X[:, 0] -= (h - w) / 2  # centred in a cell w wide
            draw_smooth(img, X, tris, col)
            out[top : top + h, x0 : x0 + w] = img
        name = f"{build} ({view})"
        tw = cv2.getTextSize(name, FONT, FONT_SCALE, 1)[0][0]
        cv2.putText(out, name, (x0 + max((w - tw) // 2, 2), LABEL - 9), FONT, FONT_SCALE, (235, 235, 235), 1,
                    cv2.LINE_AA)  # fmt: skip
        x0 += w
    out[LABEL + height, :] = (90, 90, 96)  # the close-ups' edge
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "body_builds.png"))
    ap.add_argument("--height", type=int, default=520, help="pixels from the top of the picture to the feet")
    a = ap.parse_args()
    img = sheet(a.height)
    cv2.imwrite(a.out, cv2.cvtColor(img, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_PNG_COMPRESSION, 9])
    print(f"wrote {a.out} ({img.shape[1]} x {img.shape[0]}, {Path(a.out).stat().st_size // 1024} KB)")


if __name__ == "__main__":
    main()
