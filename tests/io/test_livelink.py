"""Live Link Face packets: the layout Unreal's Live Link Face source reads, and `anima
livelink` playing a real capture into a UDP parser on 127.0.0.1 at the capture's frame rate with the values of
its arkit.csv."""

import numpy as np
import pytest
from livelink_parser import LiveLinkParser

from anima.io.livelink import N_VALUES, pack, unpack


def test_a_packet_round_trips_and_has_the_apps_layout():
    v = np.linspace(-1, 1, N_VALUES)
    b = pack("123e4567-e89b-12d3-a456-426614174000", "iPhone", 1234, 0.5, 60, v)
    assert b[:4] == (6).to_bytes(4, "little") and b[4:5] == b"$"
    assert len(b) == 4 + 37 + 4 + len("iPhone") + 8 + 8 + 1 + 4 * N_VALUES
    got = unpack(b)
    assert got["subject"] == "iPhone" and got["frame"] == 1234 and got["fps"] == 60 and got["denominator"] == 1
    np.testing.assert_allclose(got["values"], v, atol=1e-7)
    with pytest.raises(ValueError):
        unpack(b[:-3])
    with pytest.raises(ValueError):
        pack("not-a-uuid", "x", 0, 0.0, 30, v)
    with pytest.raises(ValueError):
        pack("123e4567-e89b-12d3-a456-426614174000", "x", 0, 0.0, 30, np.full(N_VALUES, np.nan))


def test_livelink_plays_a_real_capture_at_its_rate(d0_capture, tmp_path, cli):
    from anima.export.formats import export_arkit_csv
    from anima.io.arkit import read_live_link_csv
    from anima.io.sequence import write_sequence

    seq_path = write_sequence(d0_capture, tmp_path / "capture.npz")
    with LiveLinkParser() as rx:
        r = cli("livelink", seq_path, "--to", f"127.0.0.1:{rx.port}", "--subject", "take1", "--json")
    got = rx.packets
    assert r.returncode == 0, r.stderr
    assert len(got) == d0_capture.n_frames and {g[1]["subject"] for g in got} == {"take1"}
    t = np.array([g[0] for g in got])
    rate = 1.0 / np.median(np.diff(t))  # the pacing (one stall of a loaded machine does not move a median)
    assert (len(t) - 1) / (t[-1] - t[0]) >= 20 and rate >= 20 and abs(rate - d0_capture.fps) < 0.1 * d0_capture.fps, (
        rate
    )  # paced at the capture's rate
    V = np.stack([g[1]["values"] for g in got])
    assert np.isfinite(V).all() and np.ptp(V[:, :52], 0).max() > 0.3  # values that move (d0 smiles and blinks)
    _, csv = read_live_link_csv(export_arkit_csv(d0_capture, tmp_path / "a.csv"))
    np.testing.assert_allclose(V, csv, atol=1e-5)  # the values of arkit.csv
    for to, words in (("nohost", "HOST:PORT"), ("127.0.0.1:0", "HOST:PORT"), ("no.such.host.invalid:11111", "resolve")):
        r = cli("livelink", seq_path, "--to", to)
        assert r.returncode == 2 and words in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
