"""The character's 52 ARKit shapes on one sheet: its head from the front, each channel alone at 1.0, labelled
with its name (the rest face first, to compare; mouthClose over jawOpen, as ARKit means it), drawn by anima's own
rasterizer; ``docs/arkit_shapes.png``, referenced from docs/face_rig.md.

    python tools/shape_sheet.py [--out docs/arkit_shapes.png] [--cell 150] [--columns 9]

The morphs are the ones every file anima writes carries (:func:`anima.facemodel.character.arkit_morphs`), on the
mean character in its rest pose; the colours are the vertices' (:func:`anima.facemodel.character.vertex_colors`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from anima.export.avatar import head_triangles  # noqa: E402
from anima.facemodel.character import arkit_dense, load_character, vertex_colors  # noqa: E402
from anima.io.arkit import ARKIT_NAMES  # noqa: E402
from anima.render.avatar import draw_smooth, head_view  # noqa: E402

WIDTH_M = 0.16
"""How much of the face a cell shows across (metres): brows to chin, with jawOpen's chin and tongueOut's tip."""
CENTRE = (0.0, -0.012, 0.0)
"""The cell's centre from the eyes' and mouth corners' middle (metres): a little low, for the open jaw."""
LABEL = 24
FONT, FONT_SCALE = cv2.FONT_HERSHEY_SIMPLEX, 0.42
BACKGROUND = (40, 40, 44)


def face_centre(V: np.ndarray) -> np.ndarray:
    """The middle of the face's eyes and mouth: the eyeballs' and the tongue's front as found on the mesh (the
    body's vertices ahead of the head's middle and within the face's height)."""
    from anima.facemodel.character import eye_vertices, tongue_vertices

    left, right = eye_vertices()
    T = tongue_vertices()
    eyes = (V[left].mean(0) + V[right].mean(0)) / 2
    mouth = V[T[np.argmax(V[T, 2])]]
    return (eyes + mouth) / 2 + np.asarray(CENTRE)


def sheet(cell: int = 150, columns: int = 9) -> np.ndarray:
    """The sheet (RGB uint8): the rest face, then each of :data:`ARKIT_NAMES` at 1.0, ``columns`` a row."""
    ch = load_character()
    V = ch.vertices.astype(np.float64)
    D = arkit_dense().astype(np.float64)
    tris, col = head_triangles(ch), vertex_colors()
    centre = face_centre(V)
    shapes = [("(rest)", np.zeros_like(V)), *zip(ARKIT_NAMES, D)]
    k = ARKIT_NAMES.index("mouthClose")  # closes the lips over an open jaw: drawn so, as ARKit's reference does
    shapes[k + 1] = ("mouthClose+jawOpen", D[k] + D[ARKIT_NAMES.index("jawOpen")])
    rows = -(-len(shapes) // columns)
    out = np.zeros((rows * (cell + LABEL), columns * cell, 3), np.uint8)
    out[:] = BACKGROUND
    for k, (name, d) in enumerate(shapes):
        r, c = divmod(k, columns)
        img = np.zeros((cell, cell, 3), np.uint8)
        img[:] = BACKGROUND
        draw_smooth(img, head_view(V + d, cell, np.eye(3), centre, cell / WIDTH_M), tris, col)
        y0, x0 = r * (cell + LABEL), c * cell
        w = cv2.getTextSize(name, FONT, FONT_SCALE, 1)[0][0]
        cv2.putText(out, name, (x0 + max((cell - w) // 2, 2), y0 + LABEL - 9), FONT, FONT_SCALE, (235, 235, 235), 1,
                    cv2.LINE_AA)  # fmt: skip
        out[y0 + LABEL : y0 + LABEL + cell, x0 : x0 + cell] = img
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "arkit_shapes.png"))
    ap.add_argument("--cell", type=int, default=150, help="pixels a side of each face")
    ap.add_argument("--columns", type=int, default=9)
    a = ap.parse_args()
    img = sheet(a.cell, a.columns)
    cv2.imwrite(a.out, cv2.cvtColor(img, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_PNG_COMPRESSION, 9])
    print(f"wrote {a.out} ({img.shape[1]} x {img.shape[0]}, {Path(a.out).stat().st_size // 1024} KB)")


if __name__ == "__main__":
    main()
