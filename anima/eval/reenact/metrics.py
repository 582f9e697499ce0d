"""Seed 001's re-enactment metrics (section 4.2) on a face box: SSIM (Gaussian window 11, sigma 1.5, RGB
averaged over channels), LPIPS (AlexNet + linear, v0.1), lip NME (MediaPipe Face Mesh on the output and on the
real frame: the mean distance of the 40 lip landmarks over sqrt(w h) of the real frame's landmark box), tOF (eq.
2.9: the L2 norm of the difference of Farneback flows, per pixel, over frame pairs), tLP (the mean |LPIPS(out_t,
out_t+1) - LPIPS(gt_t, gt_t+1)|), and the mouth's sharpness (variance of the Laplacian)."""

from __future__ import annotations

import cv2
import numpy as np

from anima.track import get


def ssim(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a.astype(np.float64), b.astype(np.float64)
    C1, C2 = (0.01 * 255) ** 2, (0.03 * 255) ** 2
    blur = lambda x: cv2.GaussianBlur(x, (11, 11), 1.5)
    mu_a, mu_b = blur(a), blur(b)
    s_aa, s_bb, s_ab = blur(a * a) - mu_a**2, blur(b * b) - mu_b**2, blur(a * b) - mu_a * mu_b
    m = ((2 * mu_a * mu_b + C1) * (2 * s_ab + C2)) / ((mu_a**2 + mu_b**2 + C1) * (s_aa + s_bb + C2))
    return float(m.mean())


def flow(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Farneback optical flow ``[H, W, 2]`` (pixels) from RGB frame ``a`` to ``b`` (OpenCV's usual settings)."""
    ga, gb = (cv2.cvtColor(x, cv2.COLOR_RGB2GRAY) for x in (a, b))
    return cv2.calcOpticalFlowFarneback(ga, gb, None, 0.5, 3, 15, 3, 5, 1.2, 0)


def temporal_flow_error(out: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """tOF per frame pair (seed 001 eq. 2.9): the mean over pixels of ||flow(out) - flow(gt)||_2."""
    return np.array(
        [np.linalg.norm(flow(out[t], out[t + 1]) - flow(gt[t], gt[t + 1]), axis=-1).mean() for t in range(len(out) - 1)]
    )


def video_metrics(out: list[np.ndarray], gt: list[np.ndarray], box) -> dict:
    from anima.eval.reenact.lpips import lpips

    x0, y0, w, h = box
    co = np.stack([o[y0 : y0 + h, x0 : x0 + w] for o in out])
    cg = np.stack([g[y0 : y0 + h, x0 : x0 + w] for g in gt])
    s = [ssim(a, b) for a, b in zip(co, cg)]
    lp = np.concatenate([lpips(co[i : i + 32], cg[i : i + 32]) for i in range(0, len(co), 32)])
    tracker = get()
    lips = tracker.lip_landmarks()
    nme = []
    with tracker.face_mesh(static=True) as t1, tracker.face_mesh(static=True) as t2:
        for o, g in zip(out, gt):
            lo, lg = t1(o), t2(g)
            if lo is None or lg is None:
                continue
            H, W = g.shape[:2]
            po, pg = lo[lips, :2] * [W, H], lg[lips, :2] * [W, H]
            allg = lg[:, :2] * [W, H]
            wh = allg.max(0) - allg.min(0)
            nme.append(np.linalg.norm(po - pg, axis=-1).mean() / np.sqrt(wh[0] * wh[1]))
    tof = temporal_flow_error(co, cg)

    def consecutive(c):
        a, b = c[:-1], c[1:]
        return np.concatenate([lpips(a[i : i + 32], b[i : i + 32]) for i in range(0, len(a), 32)])

    lpo, lpg = consecutive(co), consecutive(cg)
    n = min(len(lpo), len(lpg))
    return {
        "ssim": float(np.mean(s)),
        "lpips": float(np.mean(lp)),
        "nme_lips": float(np.mean(nme)) if nme else None,
        "nme_frames": len(nme),
        "tof": float(np.mean(tof)) if len(tof) else None,
        "tlp": float(np.mean(np.abs(lpo[:n] - lpg[:n]))),
    }


def mouth_sharpness(frames, box) -> float:
    """Mean variance of the Laplacian of the grey face box (an edge-energy measure; blur lowers it)."""
    x0, y0, w, h = box
    return float(
        np.mean(
            [
                cv2.Laplacian(cv2.cvtColor(f[y0 : y0 + h, x0 : x0 + w], cv2.COLOR_RGB2GRAY), cv2.CV_64F).var()
                for f in frames
            ]
        )
    )
