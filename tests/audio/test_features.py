import numpy as np
import pytest

from anima.audio.features import FEATURE_NAMES, NoAudio, read_audio, speech_features
from anima.errors import InputError
from anima.io.assets import asset

WAV = "styletalk-samples/samples/source_video/wav/Obama_clip1.wav"


@pytest.fixture(scope="module")
def speech():
    return read_audio(asset(WAV))


@pytest.mark.parametrize("fps", [15.0, 25.0, 29.97, 30.0])
def test_one_row_per_motion_frame_and_finite(speech, fps):
    n = int(len(speech) / 16000 * fps)
    f = speech_features(speech, fps, n)
    assert f.features.shape == (n, 28) and len(FEATURE_NAMES) == 28
    assert np.isfinite(f.features).all() and f.valid.all() and not f.silent


@pytest.mark.parametrize("fps,shift", [(15.0, 7), (30.0, 11)])
def test_known_audio_offset_is_recovered_to_the_frame(speech, fps, shift):
    n = 200
    a = speech_features(speech, fps, n + shift)
    delayed = np.concatenate([np.zeros(int(round(shift / fps * 16000)), np.float32), speech])
    b = speech_features(delayed, fps, n + shift)
    ea, eb = a.features[:, 13], b.features[:, 13]  # log energy
    ea = (ea - ea.mean()) / ea.std()
    eb = (eb - eb.mean()) / eb.std()
    scores = [np.mean(ea[: n - k] * eb[k:n]) for k in range(2 * shift)]
    assert int(np.argmax(scores)) == shift


def test_silent_and_short_audio(speech):
    f = speech_features(np.zeros(16000, np.float32), 30.0, 30)
    assert f.silent and np.isfinite(f.features).all()
    short = speech_features(speech[:16000], 30.0, 60)  # 1 s of audio for 2 s of video
    assert short.features.shape == (60, 28)
    assert short.valid[:30].all() and not short.valid[31:].any()


def test_loudness_normalisation_makes_gain_irrelevant(speech):
    a = speech_features(speech, 30.0, 100)
    b = speech_features(speech * 0.1, 30.0, 100)
    assert np.abs(a.features - b.features).max() < 1e-2


def test_audio_track_of_a_video_and_missing_audio():
    x = read_audio(asset("talking-heads-misc/LatentSync/assets/demo1_video.mp4"))
    assert abs(len(x) / 16000 - 10.0) < 0.1
    with pytest.raises(NoAudio):
        read_audio(asset("liveportrait-examples/assets/examples/driving/d0.mp4"))
    with pytest.raises(InputError):
        read_audio("/nonexistent.wav")


def test_each_step_equals_librosa_on_real_speech(speech):
    """The feature maths is written out in numpy (no librosa import in a command); every step agrees with
    librosa itself, and so do the features of the old librosa pipeline, on real speech."""
    import librosa
    import scipy.signal

    from anima.audio import features as F

    np.testing.assert_allclose(F.hann(400), scipy.signal.get_window("hann", 400, fftbins=True), atol=1e-12)
    np.testing.assert_allclose(F.mel_filters(), librosa.filters.mel(sr=16000, n_fft=512, n_mels=40), atol=1e-7)
    x = speech[:48000]
    np.testing.assert_array_equal(F.frame_signal(x, 320, 160), librosa.util.frame(x, frame_length=320, hop_length=160))
    base = np.random.default_rng(0).normal(size=(50, 14))
    np.testing.assert_allclose(F.delta3(base), librosa.feature.delta(base, width=3, order=1, axis=0), atol=1e-12)
    import scipy.fft

    S = np.random.default_rng(1).normal(size=(40, 30))
    np.testing.assert_allclose(F.dct_ortho(40, 13) @ S, scipy.fft.dct(S, type=2, norm="ortho", axis=0)[:13], atol=1e-12)
    # the whole pipeline as it was written with librosa
    fps, n = 30.0, 120
    y, _, _ = F.normalize_loudness(x)
    centres = np.round(np.arange(n) / fps * 16000).astype(np.int64)
    fr = F._centred_frames(y, centres, 400) * librosa.filters.get_window("hann", 400, fftbins=True)[None]
    mel = librosa.filters.mel(sr=16000, n_fft=512, n_mels=40) @ (np.abs(np.fft.rfft(fr, n=512, axis=1)) ** 2).T
    mfcc = librosa.feature.mfcc(S=librosa.power_to_db(mel, ref=1.0, amin=1e-10, top_db=None), n_mfcc=13)
    ours = speech_features(x, fps, n).features
    np.testing.assert_allclose(ours[:, :13], mfcc.T, atol=2e-4)
    np.testing.assert_allclose(ours[:, 14:27], librosa.feature.delta(mfcc.T, width=3, order=1, axis=0), atol=2e-4)
