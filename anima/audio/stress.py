"""The stressed syllables of speech: where a speaker's gesture strokes belong. Pure numpy (no librosa import: the
gesture command starts in about a second).

1. Per 10-ms frame of the loudness-normalised 16-kHz signal (:func:`anima.audio.features.normalize_loudness`): the
   intensity (dB, 25-ms window, smoothed over 50 ms), the onset strength (the spectral flux of the 40-band log-mel
   spectrum: its mean rise over the bands, librosa's ``onset_strength`` recipe) and the pitch (the autocorrelation
   method on the signal at 8 kHz: the highest normalised autocorrelation peak between 75 and 400 Hz of a 50-ms Hann
   frame, divided by the window's own autocorrelation; voiced where it is at least 0.45 and the frame is within
   35 dB of the loudest).
2. Syllable nuclei (de Jong and Wempe 2009): voiced intensity peaks above the utterance's median intensity with a
   dip of at least 2 dB before them (a smaller dip merges two peaks into the louder one).
3. Each nucleus is scored by how much it stands out from its neighbours within +-1.5 s: its intensity, its pitch
   (semitones above the local median: a pitch accent) and the onset strength in the 150 ms before it, each divided
   by its spread over the utterance's nuclei, summed. The nuclei that score above the local median of the scores
   are stressed; of two stresses closer than 0.3 s the weaker goes.
4. A stress is placed at its syllable's onset: the peak of the onset strength in the 150 ms before the nucleus.

Not validated against hand-labelled prosody (no such labels in the shared data): a heuristic whose use is to time
gesture strokes (``anima.gesture.strokes``), measured there by how close strokes land.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from anima.audio.features import SR, frame_signal, hann, mel_filters, normalize_loudness

FRAME_HOP = SR // 100  # 10-ms frames
FRAME_S = FRAME_HOP / SR
WIN = SR // 40  # 25 ms: intensity and spectrum
N_FFT = 512
PITCH_WIN = SR // 20  # 50 ms: two periods of the lowest pitch
F0_MIN, F0_MAX = 75.0, 400.0
VOICING = 0.45
ACTIVE_DB = 35.0
DIP_DB = 2.0
LOCAL_S = 1.5
ONSET_S = 0.15
MIN_GAP_S = 0.3
_CHUNK = 4096


@dataclass
class Prosody:
    """Per 10-ms frame (frame i centred on ``i * FRAME_S`` seconds)."""

    intensity_db: np.ndarray
    onset: np.ndarray
    f0_hz: np.ndarray  # NaN where unvoiced
    frame_s: float = FRAME_S


@dataclass
class Stresses:
    times_s: np.ndarray  # the stressed syllables' onsets, seconds
    strength: np.ndarray  # their scores (larger: more prominent)
    nuclei_s: np.ndarray  # every syllable nucleus found (seconds)

    def frames(self, fps: float) -> np.ndarray:
        """The stresses' times in frames at ``fps`` (fractional)."""
        return self.times_s * fps


def _frames(x: np.ndarray, length: int, hop: int = FRAME_HOP) -> np.ndarray:
    """``[n, length]`` view: frame i centred on sample ``i * hop`` (zeros outside the signal)."""
    n = len(x) // hop + 1
    pad = np.pad(x.astype(np.float32), (length // 2, length + n * hop - len(x)))
    return frame_signal(pad, length, hop).T[:n]


def _smooth(x: np.ndarray, sigma: float) -> np.ndarray:
    r = int(np.ceil(3 * sigma))
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    k /= k.sum()
    return np.convolve(np.pad(x, r, mode="edge"), k, mode="valid")


def prosody(x: np.ndarray) -> Prosody:
    """Intensity, onset strength and pitch of 16-kHz mono samples ``x`` (see the module docstring)."""
    x, _, _ = normalize_loudness(np.asarray(x, np.float32))
    fr = _frames(x, WIN)
    n = len(fr)
    # pitch at 8 kHz (up to 400 Hz: plenty), half the transform sizes
    x8 = np.convolve(np.pad(x, 1, mode="edge"), [0.25, 0.5, 0.25], mode="valid")[::2]
    sr8, win8 = SR // 2, PITCH_WIN // 2
    pf = _frames(x8, win8, FRAME_HOP // 2)[:n]
    w = hann(WIN).astype(np.float32)
    mel = mel_filters(SR, N_FFT)
    pw = hann(win8)
    lo, hi = int(sr8 / F0_MAX), int(np.ceil(sr8 / F0_MIN))
    nfft_p = 1 << int(np.ceil(np.log2(win8 + hi + 2)))  # long enough that lags up to hi do not wrap around
    rw = np.fft.irfft(np.abs(np.fft.rfft(pw, nfft_p)) ** 2)[: hi + 2]
    energy = np.empty(n)
    logmel = np.empty((n, mel.shape[0]))
    f0 = np.full(n, np.nan)
    for c in range(0, n, _CHUNK):
        f = fr[c : c + _CHUNK].astype(np.float64)
        energy[c : c + _CHUNK] = (f * f).mean(1)
        spec = np.abs(np.fft.rfft(f * w, N_FFT)) ** 2
        logmel[c : c + _CHUNK] = 10 * np.log10(np.maximum(spec @ mel.T, 1e-10))
    db = 10 * np.log10(energy + 1e-10)
    active = np.flatnonzero(db >= db.max() - ACTIVE_DB)  # pitch only where there is sound
    for c in range(0, len(active), _CHUNK):
        rows = active[c : c + _CHUNK]
        p = pf[rows].astype(np.float64)
        p = (p - p.mean(1, keepdims=True)) * pw
        r = np.fft.irfft(np.abs(np.fft.rfft(p, nfft_p)) ** 2)[:, : hi + 2]
        r = r / np.maximum(r[:, :1], 1e-12) / (rw[: hi + 2] / rw[0])
        seg = r[:, lo : hi + 1]
        k = seg.argmax(1)
        best = seg[np.arange(len(seg)), k]
        tau = (k + lo).astype(np.float64)
        ok = (k > 0) & (k < seg.shape[1] - 1)  # parabolic refinement of the lag
        a, b, d = seg[ok, k[ok] - 1], seg[ok, k[ok]], seg[ok, k[ok] + 1]
        den = a - 2 * b + d
        tau[ok] += np.where(np.abs(den) > 1e-12, 0.5 * (a - d) / np.where(den == 0, 1, den), 0.0)
        f0[rows] = np.where(best >= VOICING, sr8 / tau, np.nan)
    logmel = np.maximum(logmel, logmel.max() - 80.0)
    onset = np.zeros(n)
    onset[1:] = np.maximum(np.diff(logmel, axis=0), 0).mean(1)
    return Prosody(_smooth(db, 2.0), onset, _median5(f0))


def _median5(f0: np.ndarray) -> np.ndarray:
    """A 5-frame median over voiced frames (octave jumps of single frames removed); unvoiced stays NaN."""
    if len(f0) < 5:
        return f0
    win = np.lib.stride_tricks.sliding_window_view(np.pad(f0, 2, constant_values=np.nan), 5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # an all-unvoiced window's median is NaN, as it should be
        med = np.nanmedian(win, axis=1)
    return np.where(np.isfinite(f0), med, np.nan)


def nuclei(p: Prosody) -> np.ndarray:
    """Frame indices of the syllable nuclei (see the module docstring)."""
    I = p.intensity_db
    voiced = np.isfinite(p.f0_hz)
    if not voiced.any() or len(I) < 3:
        return np.zeros(0, int)
    near_voiced = np.convolve(voiced.astype(float), np.ones(5), mode="same") > 0
    floor = np.median(I[I > I.max() - ACTIVE_DB])
    peaks = np.flatnonzero((I[1:-1] > I[:-2]) & (I[1:-1] >= I[2:])) + 1
    peaks = peaks[(I[peaks] > floor) & near_voiced[peaks]]
    out: list[int] = []
    for q in peaks:
        if out and I[out[-1] : q + 1].min() > I[q] - DIP_DB:  # no dip between: one syllable, keep the louder
            if I[q] > I[out[-1]]:
                out[-1] = int(q)
            continue
        out.append(int(q))
    return np.array(out, int)


def _local(values: np.ndarray, times: np.ndarray, fn) -> np.ndarray:
    out = np.empty(len(values))
    for i, t in enumerate(times):
        near = np.abs(times - t) <= LOCAL_S
        v = values[near & np.isfinite(values)]
        out[i] = fn(v) if len(v) else np.nan
    return out


def _spread(x: np.ndarray) -> float:
    x = x[np.isfinite(x)]
    if len(x) < 2:
        return 1.0
    mad = 1.4826 * np.median(np.abs(x - np.median(x)))
    return float(mad if mad > 1e-9 else (x.std() or 1.0))


def find_stresses(x: np.ndarray) -> Stresses:
    """The stressed syllables of 16-kHz mono speech ``x`` (see the module docstring). Silence: none."""
    p = prosody(x)
    nu = nuclei(p)
    if not len(nu):
        return Stresses(np.zeros(0), np.zeros(0), np.zeros(0))
    t = nu * p.frame_s
    back = int(round(ONSET_S / p.frame_s))
    onset_at = np.array([max(0, q - back) + int(np.argmax(p.onset[max(0, q - back) : q + 1])) for q in nu])
    inten = p.intensity_db[nu]
    st = np.full(len(nu), np.nan)
    voiced = np.isfinite(p.f0_hz)
    vt = np.flatnonzero(voiced) * p.frame_s
    semis = 12 * np.log2(np.where(voiced, p.f0_hz, 1.0) / 100.0)
    for i, q in enumerate(nu):  # the nucleus's pitch: the voiced frames within 30 ms
        v = semis[max(0, q - 3) : q + 4][voiced[max(0, q - 3) : q + 4]]
        if len(v):
            st[i] = v.max()
    local_pitch = np.array(
        [np.median(semis[voiced][np.abs(vt - ti) <= LOCAL_S]) if voiced.any() else np.nan for ti in t]
    )
    onset = np.log(np.array([p.onset[max(0, q - back) : q + 1].max() for q in nu]) + 1e-3)
    e = inten - _local(inten, t, np.median)
    f = np.nan_to_num(st - local_pitch)
    o = onset - _local(onset, t, np.median)
    score = e / _spread(e) + f / _spread(f) + o / _spread(o)
    stressed = score > _local(score, t, np.median)
    if len(nu) == 1:
        stressed[:] = True
    idx = np.flatnonzero(stressed)
    keep: list[int] = []
    for i in idx[np.argsort(-score[idx], kind="stable")]:  # strongest first; a weaker one within 0.3 s goes
        if all(abs(onset_at[i] - onset_at[j]) * p.frame_s >= MIN_GAP_S for j in keep):
            keep.append(int(i))
    keep.sort()
    return Stresses(onset_at[keep] * p.frame_s, score[keep], t)
