"""Joining a long video's tracked chunks (the dataset build's chunk tasks) into one video's tracking."""

import numpy as np

from anima.capture.pipeline import Tracked, join_chunks


def _part(a: int, b: int, warnings=()) -> Tracked:
    lm = np.full((b - a, 478, 3), float(a), np.float32) + np.arange(b - a, dtype=np.float32)[:, None, None]
    return Tracked(lm, [f"frame {k}" for k in range(a, b)], list(warnings))


def test_chunks_join_in_order_and_say_how_they_were_cut():
    plan = [(0, 4), (4, 9), (9, 12)]
    t = join_chunks([_part(a, b) for a, b in plan], plan, warmup=25)
    assert t.frames == [f"frame {k}" for k in range(12)]
    assert np.array_equal(t.landmarks[:, 0, 0], np.arange(12, dtype=np.float32))
    assert t.chunks == {"chunks": 3, "frames": [[0, 4], [4, 9], [9, 12]], "warmup_frames": 25} and not t.warnings


def test_decoding_that_stops_inside_a_chunk_ends_the_video_there():
    """As a whole-video pass keeps the frames decoded before an error, so does the join: the chunks after the
    failing one are dropped (their frames would otherwise be glued on after a hole)."""
    plan = [(0, 4), (4, 9), (9, 12)]
    parts = [_part(0, 4), _part(4, 6, ["decoding stopped early (x)"]), _part(9, 12)]
    t = join_chunks(parts, plan, warmup=0)
    assert len(t.frames) == 6 and t.landmarks.shape[0] == 6
    assert t.warnings[0].startswith("decoding stopped early") and "ends there" in t.warnings[-1]
    # a last chunk that stops early simply ends the video
    t = join_chunks([_part(0, 4), _part(4, 9), _part(9, 10, ["decoding stopped early (x)"])], plan, warmup=0)
    assert len(t.frames) == 10 and len(t.warnings) == 1
