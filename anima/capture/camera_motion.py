"""The camera's own motion, from the background: a panning or tilting camera moves everything in the picture,
the person included, so the person's travel is their picture track minus the background's.

Per frame (:class:`BackgroundMotion`): corners (Shi-Tomasi) of the previous frame outside the person's box
(the pose landmarks' bounding box, enlarged by a quarter) are followed into this frame by pyramidal
Lucas-Kanade optical flow on a grey copy at most :data:`WORK_WIDTH` pixels wide; a similarity transform is
fitted to the pairs with RANSAC; the frame's camera step is its displacement of the person's centre (in the
picture's pixels) and the log of its scale (a zoom or a dolly). Too few background points (a person filling
the picture, a blank wall): the step is 0 (a still camera is assumed). OpenCV's implementations throughout;
a few milliseconds a frame."""

from __future__ import annotations

import cv2
import numpy as np

WORK_WIDTH = 320
MIN_POINTS = 12


class BackgroundMotion:
    """``step = bm(rgb, pose)``: the background's shift and log scale ``[3]`` (pixels of ``rgb``) since the
    previous call (0 at the first); ``pose``: MediaPipe's normalised pose landmarks ``[33, >=2]`` or None."""

    def __init__(self):
        self.prev = None
        self.scale = 1.0

    def __call__(self, rgb: np.ndarray, pose: np.ndarray | None) -> np.ndarray:
        H, W = rgb.shape[:2]
        self.scale = min(1.0, WORK_WIDTH / W)
        small = cv2.resize(
            rgb, (max(8, int(W * self.scale)), max(8, int(H * self.scale))), interpolation=cv2.INTER_AREA
        )
        grey = cv2.cvtColor(small, cv2.COLOR_RGB2GRAY)
        h, w = grey.shape
        mask = np.full((h, w), 255, np.uint8)
        centre = np.array([w / 2, h / 2])
        if pose is not None:
            xy = pose[:, :2] * [w, h]
            lo, hi = xy.min(0), xy.max(0)
            pad = 0.25 * (hi - lo)
            a = np.clip(lo - pad, 0, [w, h]).astype(int)
            b = np.clip(hi + pad, 0, [w, h]).astype(int)
            mask[a[1] : b[1], a[0] : b[0]] = 0
            centre = (lo + hi) / 2
        step = np.zeros(3)
        if self.prev is not None:
            prev, prev_mask = self.prev
            pts = cv2.goodFeaturesToTrack(prev, 200, 0.01, 6, mask=prev_mask)
            if pts is not None and len(pts) >= MIN_POINTS:
                nxt, ok, _ = cv2.calcOpticalFlowPyrLK(prev, grey, pts, None, winSize=(15, 15), maxLevel=2)
                ok = ok.ravel() == 1
                if ok.sum() >= MIN_POINTS:
                    M, inl = cv2.estimateAffinePartial2D(pts[ok], nxt[ok], method=cv2.RANSAC, ransacReprojThreshold=1.5)
                    if M is not None and inl is not None and inl.sum() >= MIN_POINTS:
                        step[:2] = (M[:, :2] @ centre + M[:, 2] - centre) / self.scale
                        step[2] = np.log(max(1e-3, float(np.sqrt(abs(np.linalg.det(M[:, :2]))))))
        self.prev = (grey, mask)
        return step
