"""Speech features at motion frame times: 13 MFCC + log mean energy and their first derivatives (28).

Alignment: feature row i describes the audio centred on the motion frame's time ``t_i = i / fps``
(frame i of a video is displayed from t_i). MFCC use a 25 ms Hann window (n_fft 512 at 16 kHz) centred
exactly on ``round(t_i * sr)``; the log mean energy is the log of the mean power over one motion-frame
period centred on t_i. Samples outside the audio count as silence. First derivatives are centred
differences along the motion-frame axis (``librosa.feature.delta``, width 3).

The maths is librosa's (Slaney mel filters, orthonormal DCT-II, Savitzky-Golay deltas), written out in
numpy alone so a command does not pay librosa's import (about 1.5 s of numba compilation);
``tests/audio`` checks every step against librosa itself.

Loudness: the signal is scaled so that its active part (frames within 40 dB of the loudest) has an RMS of
-20 dBFS, so features do not depend on recording gain.
"""

from __future__ import annotations

import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from anima.core.contract import N_MFCC
from anima.errors import InputError
from anima.io.atomic import write_npz
from anima.io.outdir import check_out_file
from anima.io.owned import npz
from anima.io.video import FFMPEG

SR = 16000
N_FFT = 512
WIN = 400  # 25 ms
N_MELS = 40
TARGET_DBFS = -20.0
SILENCE_DBFS = -60.0
FEATURE_NAMES = (
    [f"mfcc{i}" for i in range(N_MFCC)] + ["log_energy"] + [f"d_mfcc{i}" for i in range(N_MFCC)] + ["d_log_energy"]
)


SPEECH_NPZ = npz("features", "valid", "fps", "names")  # what `anima audio features` writes


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


MAX_AUDIO_S = 3600.0
"""``anima audio features``' longest audio (one hour, the longest --seconds of any command): its decoded samples
and features take about 2.3 GB; a longer file is refused after decoding at most this much."""


def read_audio(path: str | Path, sr: int = SR, max_s: float | None = None) -> np.ndarray:
    """Decode the first audio stream of any file ffmpeg reads (WAV, MP3, FLAC, the audio of a video) to
    mono float32 at ``sr``. Raises :class:`NoAudio` when there is no audio stream. ``max_s``: the longest audio
    taken; ffmpeg decodes at most a little more (whatever the container claims), and a longer one is refused."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"audio file not found: {p}")
    # a little past the limit, so a longer file shows itself (a file of exactly max_s is taken)
    until = [] if max_s is None else ["-t", f"{max_s + 0.5:.3f}"]
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
        *until,
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
    if max_s is not None and x.size > (max_s + 0.1) * sr:
        raise InputError(f"{p}: the audio is longer than {max_s:g} s ({max_s / 60:g} min), the most this command takes")
    if not np.isfinite(x).all():
        raise InputError(f"{p}: the audio holds NaN or infinite samples (a damaged float WAV)")
    return x.copy()


def frame_signal(x: np.ndarray, length: int, hop: int) -> np.ndarray:
    """``librosa.util.frame``: windows of ``length`` samples every ``hop`` samples, ``[length, n]`` (a view)."""
    return np.lib.stride_tricks.sliding_window_view(x, length)[::hop].T


def hann(n: int) -> np.ndarray:
    """Periodic Hann window (``scipy.signal.get_window("hann", n, fftbins=True)``)."""
    return 0.5 - 0.5 * np.cos(2 * np.pi * np.arange(n) / n)


def dct_ortho(n: int, k: int) -> np.ndarray:
    """The first ``k`` rows of the orthonormal DCT-II matrix of size ``n`` (``scipy.fft.dct(x, type=2,
    norm="ortho", axis=0)[:k] == dct_ortho(n, k) @ x``): a [k, n] product instead of importing scipy.fft and
    scipy.special with it (0.07 s of a command's start)."""
    m = np.cos(np.pi / n * (np.arange(n)[None] + 0.5) * np.arange(k)[:, None]) * np.sqrt(2.0 / n)
    m[0] /= np.sqrt(2.0)
    return m


def _hz_to_mel(f):
    """Slaney's mel scale (librosa's default, ``htk=False``): linear below 1 kHz, logarithmic above."""
    f = np.asarray(f, np.float64)
    f_sp, min_log_hz = 200.0 / 3, 1000.0
    min_log_mel, logstep = min_log_hz / f_sp, np.log(6.4) / 27.0
    return np.where(f >= min_log_hz, min_log_mel + np.log(np.maximum(f, 1e-12) / min_log_hz) / logstep, f / f_sp)


def _mel_to_hz(m):
    m = np.asarray(m, np.float64)
    f_sp, min_log_hz = 200.0 / 3, 1000.0
    min_log_mel, logstep = min_log_hz / f_sp, np.log(6.4) / 27.0
    return np.where(m >= min_log_mel, min_log_hz * np.exp(logstep * (m - min_log_mel)), f_sp * m)


def mel_filters(sr: int = SR, n_fft: int = N_FFT, n_mels: int = N_MELS) -> np.ndarray:
    """``librosa.filters.mel(sr=sr, n_fft=n_fft, n_mels=n_mels)``: triangular filters on Slaney's mel scale
    from 0 Hz to sr / 2, each of unit area ("slaney" norm), ``[n_mels, 1 + n_fft / 2]`` float32."""
    fft_f = np.fft.rfftfreq(n_fft, 1.0 / sr)
    mel_f = _mel_to_hz(np.linspace(_hz_to_mel(0.0), _hz_to_mel(sr / 2.0), n_mels + 2))
    fdiff = np.diff(mel_f)
    ramps = np.subtract.outer(mel_f, fft_f)
    lower = -ramps[:-2] / fdiff[:-1, None]
    upper = ramps[2:] / fdiff[1:, None]
    w = np.maximum(0.0, np.minimum(lower, upper))
    w *= (2.0 / (mel_f[2 : n_mels + 2] - mel_f[:n_mels]))[:, None]
    return w.astype(np.float32)


def delta3(x: np.ndarray) -> np.ndarray:
    """``librosa.feature.delta(x, width=3, order=1, axis=0)`` (Savitzky-Golay, mode "interp"): centred
    differences (x[i+1] - x[i-1]) / 2 inside; the two first and two last rows take the slope of the line
    through their three-row window's ends. Needs at least 3 rows."""
    d = np.empty_like(x)
    d[1:-1] = (x[2:] - x[:-2]) / 2
    d[0], d[-1] = d[1], d[-2]
    return d


def normalize_loudness(x: np.ndarray, sr: int = SR) -> tuple[np.ndarray, float, bool]:
    """Scale the active part to TARGET_DBFS RMS. Returns (signal, gain in dB, silent?)."""
    hop = sr // 100
    frames = frame_signal(np.pad(x, (0, max(0, hop * 2 - len(x)))), hop * 2, hop)
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
    fr = _centred_frames(x, centres, WIN) * hann(WIN)[None]
    spec = np.abs(np.fft.rfft(fr, n=N_FFT, axis=1)) ** 2  # (F, 257)
    mel = mel_filters(sr, N_FFT, N_MELS) @ spec.T  # (40, F)
    db = 10.0 * np.log10(np.maximum(mel, 1e-10))  # librosa.power_to_db(ref=1, amin=1e-10, top_db=None)
    mfcc = dct_ortho(N_MELS, N_MFCC) @ db  # librosa.feature.mfcc
    period = max(int(round(sr / fps)), 1)
    energy = np.log((_centred_frames(x, centres, period).astype(np.float64) ** 2).mean(1) + 1e-10)
    base = np.concatenate([mfcc.T, energy[:, None]], 1)  # (F, 14)
    if n_frames >= 3:
        d = delta3(base)
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
    check_out_file(dest, inputs=[path], suffixes=(".npz",), ours=SPEECH_NPZ, what="a speech-features file")
    x = read_audio(path, max_s=MAX_AUDIO_S)
    longest = 2 * int(np.ceil(len(x) / SR * fps)) + 1
    if n_frames is not None and not 1 <= n_frames <= longest:
        raise InputError(
            f"--frames {n_frames}: the audio is {len(x) / SR:.2f} s, so at most {longest} frames at "
            f"{fps:g} fps (2 x its length)"
        )
    f = speech_features(x, fps, n_frames)
    write_npz(dest, features=f.features, valid=f.valid, fps=np.float32(f.fps), names=np.asarray(FEATURE_NAMES))
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
