"""Speech features at motion frame times: 13 MFCC + log mean energy and their first derivatives (28).

Alignment: feature row i describes the audio centred on the motion frame's time ``t_i = i / fps``
(frame i of a video is displayed from t_i). MFCC use a 25 ms Hann window (n_fft 512 at 16 kHz) centred
exactly on ``round(t_i * sr)``; the log mean energy is the log of the mean power over one motion-frame
period centred on t_i. Samples outside the audio count as silence. First derivatives are centred
differences along the motion-frame axis (``librosa.feature.delta``, width 3).

Loudness: the signal is scaled so that its active part (frames within 40 dB of the loudest) has an RMS of
-20 dBFS, so features do not depend on recording gain.
"""

from __future__ import annotations

import subprocess
from dataclasses import dataclass
from pathlib import Path

import librosa
import numpy as np

from anima.errors import InputError
from anima.io.atomic import atomic_path
from anima.io.outdir import check_out_file
from anima.io.video import FFMPEG

SR = 16000
N_MFCC = 13
N_FFT = 512
WIN = 400  # 25 ms
N_MELS = 40
TARGET_DBFS = -20.0
SILENCE_DBFS = -60.0
FEATURE_NAMES = (
    [f"mfcc{i}" for i in range(N_MFCC)] + ["log_energy"] + [f"d_mfcc{i}" for i in range(N_MFCC)] + ["d_log_energy"]
)


class NoAudio(InputError):
    """The file has no audio stream."""


@dataclass
class SpeechFeatures:
    features: np.ndarray  # (F, 28) float32
    fps: float
    valid: np.ndarray  # (F,) bool: the frame's centre lies inside the audio
    silent: bool  # the whole audio is below SILENCE_DBFS
    duration_s: float
    gain_db: float

    names = FEATURE_NAMES


def read_audio(path: str | Path, sr: int = SR) -> np.ndarray:
    """Decode the first audio stream of any file ffmpeg reads (WAV, MP3, FLAC, the audio of a video) to
    mono float32 at ``sr``. Raises :class:`NoAudio` when there is no audio stream."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"audio file not found: {p}")
    cmd = [
        FFMPEG,
        "-hide_banner",
        "-nostdin",
        "-v",
        "error",
        "-i",
        str(p),
        "-map",
        "0:a:0",
        "-vn",
        "-ac",
        "1",
        "-ar",
        str(sr),
        "-f",
        "f32le",
        "-",
    ]
    res = subprocess.run(cmd, capture_output=True, timeout=600)
    err = res.stderr.decode(errors="replace").strip()
    if res.returncode != 0:
        if "matches no streams" in err or "Stream map" in err:
            raise NoAudio(f"no audio track in {p}")
        raise InputError(f"cannot read audio from {p}: {err.splitlines()[-1] if err else 'ffmpeg failed'}")
    x = np.frombuffer(res.stdout, np.float32)
    if x.size == 0:
        raise NoAudio(f"the audio track of {p} is empty")
    return x.copy()


def normalize_loudness(x: np.ndarray, sr: int = SR) -> tuple[np.ndarray, float, bool]:
    """Scale the active part to TARGET_DBFS RMS. Returns (signal, gain in dB, silent?)."""
    hop = sr // 100
    frames = librosa.util.frame(np.pad(x, (0, max(0, hop * 2 - len(x)))), frame_length=hop * 2, hop_length=hop)
    rms = np.sqrt((frames.astype(np.float64) ** 2).mean(0) + 1e-20)
    db = 20 * np.log10(rms)
    if db.max() < SILENCE_DBFS:
        return x, 0.0, True
    active = rms[db > db.max() - 40]
    level = 20 * np.log10(np.sqrt((active**2).mean()))
    gain = TARGET_DBFS - level
    return (x * 10 ** (gain / 20)).astype(np.float32), float(gain), False


def _centred_frames(x: np.ndarray, centres: np.ndarray, length: int) -> np.ndarray:
    half = length // 2
    pad = np.pad(x, (half + 1, half + length + 1))
    idx = centres[:, None] + np.arange(-half, length - half)[None] + half + 1
    idx = np.clip(idx, 0, len(pad) - 1)
    return pad[idx]


def speech_features(
    x: np.ndarray, fps: float, n_frames: int | None = None, sr: int = SR, normalize: bool = True
) -> SpeechFeatures:
    """Features ``[n_frames, 28]`` at motion frame times ``i / fps`` (default: as many frames as the audio
    covers)."""
    if fps <= 0:
        raise ValueError("fps must be positive")
    duration = len(x) / sr
    if n_frames is None:
        n_frames = int(np.floor(duration * fps)) + 1 if len(x) else 0
    gain, silent = 0.0, False
    if normalize:
        x, gain, silent = normalize_loudness(x, sr)
    centres = np.round(np.arange(n_frames) / fps * sr).astype(np.int64)
    win = librosa.filters.get_window("hann", WIN, fftbins=True)
    fr = _centred_frames(x, centres, WIN) * win[None]
    spec = np.abs(np.fft.rfft(fr, n=N_FFT, axis=1)) ** 2  # (F, 257)
    mel = librosa.filters.mel(sr=sr, n_fft=N_FFT, n_mels=N_MELS) @ spec.T  # (40, F)
    mfcc = librosa.feature.mfcc(S=librosa.power_to_db(mel, ref=1.0, amin=1e-10, top_db=None), n_mfcc=N_MFCC)
    period = max(int(round(sr / fps)), 1)
    energy = np.log((_centred_frames(x, centres, period).astype(np.float64) ** 2).mean(1) + 1e-10)
    base = np.concatenate([mfcc.T, energy[:, None]], 1)  # (F, 14)
    if n_frames >= 3:
        d = librosa.feature.delta(base, width=3, order=1, axis=0)
    else:
        d = np.zeros_like(base)
    feats = np.concatenate([base, d], 1).astype(np.float32)
    valid = centres < len(x)
    return SpeechFeatures(feats, float(fps), valid, silent, duration, gain)


def features_for_file(path: str | Path, fps: float, n_frames: int | None = None) -> SpeechFeatures:
    return speech_features(read_audio(path), fps, n_frames)


def write_speech_features(
    path: str | Path, fps: float, n_frames: int | None = None, out: str | Path | None = None
) -> dict:
    """``anima audio features``: the features of ``path`` written to ``out`` (default ``<path>.speech.npz``:
    ``features [F, 28]``, ``valid [F]``, ``fps``, ``names``). Returns a summary."""
    dest = Path(out) if out else Path(path).with_suffix(".speech.npz")
    check_out_file(dest)
    x = read_audio(path)
    longest = 2 * int(np.ceil(len(x) / SR * fps)) + 1
    if n_frames is not None and not 1 <= n_frames <= longest:
        raise InputError(
            f"--frames {n_frames}: the audio is {len(x) / SR:.2f} s, so at most {longest} frames at "
            f"{fps:g} fps (2 x its length)"
        )
    f = speech_features(x, fps, n_frames)
    with atomic_path(dest) as tmp:
        np.savez_compressed(
            tmp, features=f.features, valid=f.valid, fps=np.float32(f.fps), names=np.asarray(FEATURE_NAMES)
        )
    return {
        "file": str(path),
        "out": str(dest),
        "frames": int(len(f.features)),
        "fps": f.fps,
        "duration_s": round(f.duration_s, 3),
        "silent": f.silent,
        "gain_db": round(f.gain_db, 2),
        "frames_outside_audio": int((~f.valid).sum()),
    }
