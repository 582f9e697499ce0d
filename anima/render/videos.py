"""Videos people look at: the fitted mesh over the input, the fitted mesh alone, and the tracked skeleton over
the input, all from one pass over the source."""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path

import numpy as np
from tqdm import tqdm

from anima.facemodel.ict import load_face_model
from anima.io.sequence import FLAG_NO_FACE, TrackedSequence
from anima.io.video import VideoWriter, iter_frames, probe_video
from anima.render.face import compose, put_label, raster_mesh
from anima.render.skeleton import draw_skeleton


class SequenceMesh:
    """Per-frame camera-space vertices of the fitted skin mesh."""

    def __init__(self, seq: TrackedSequence):
        self.model = load_face_model().skin()
        self.tris = np.ascontiguousarray(self.model.triangles(), np.int64)  # as the rasterizer takes them
        self.seq = seq
        self.base = self.model.vertices(seq.identity)
        self.R = seq.rotation_matrices()
        self.deltas = np.ascontiguousarray(self.model.expr_deltas.reshape(len(self.model.expr_deltas), -1))

    def camera_vertices(self, f: int) -> np.ndarray:
        V = self.base + (self.seq.expression[f].astype(np.float32) @ self.deltas).reshape(-1, 3)
        return self.seq.scale[f] * V @ self.R[f].T + self.seq.translation[f]


def render_videos(
    seq: TrackedSequence,
    video: str | None,
    overlay_path: str | Path | None,
    mesh_path: str | Path | None,
    progress: bool = True,
    alpha: float = 0.55,
    audio: str | None = None,
    skeleton_path: str | Path | None = None,
) -> None:
    """Write the overlay (mesh over the input frames, needs ``video``), the mesh-only render and/or the
    skeleton overlay (the tracked 2D joints over the input frames: needs ``video`` and ``seq.body_image``),
    decoding the source once for all three. The mesh-only video is drawn frames (flat background, one shaded
    mesh) and is encoded as such (:data:`anima.io.video.DRAWN`). The source's audio track, if any (else
    ``audio``, e.g. the speech a face was generated from), is muxed into each."""
    size = (seq.width, seq.height)
    frames = None
    if video is not None:
        info = probe_video(video)
        audio = video if info.has_audio else audio
        frames = iter_frames(info)
    face = (overlay_path is not None and frames is not None) or mesh_path is not None
    mesh = SequenceMesh(seq) if face else None
    skeleton = skeleton_path is not None and frames is not None and seq.body_image is not None
    with ExitStack() as stack:
        if frames is not None:
            stack.callback(frames.close)

        def writer(path, on: bool, drawn: bool = False):
            return stack.enter_context(VideoWriter(path, seq.fps, size, audio, drawn=drawn)) if on else None

        w_over = writer(overlay_path, bool(overlay_path) and frames is not None)
        w_mesh = writer(mesh_path, bool(mesh_path), drawn=True)
        w_skel = writer(skeleton_path, skeleton)
        for f in tqdm(range(seq.n_frames), desc="render", unit="fr", disable=not progress, leave=False):
            frame = next(frames, None) if frames is not None else None
            no_face = bool(seq.flags[f] & FLAG_NO_FACE)
            # once for both videos; the skin's back faces are left out: the mouth and the eye sockets show what is
            # behind them (the person's own mouth and eyes in the overlay), at half the raster's work
            r = raster_mesh(mesh.camera_vertices(f), mesh.tris, size, back_faces=False) if face else None
            if w_over is not None and frame is not None:
                img = frame if no_face else compose(r, size, background=frame, alpha=alpha)
                w_over.write(put_label(img, "no face" if no_face else f"fit {seq.fit_error_px[f]:.1f}px"))
            if w_mesh is not None:
                img = compose(r, size)
                w_mesh.write(put_label(img, "no face (interpolated)") if no_face else img)
            if w_skel is not None and frame is not None:
                w_skel.write(draw_skeleton(frame, seq.body_image[f], max(2, seq.width // 256)))
