"""Keyword-triggered databases (seed 004 §5.4.2): while a keyword is spoken, the next gesture is taken from a
separate database of gestures that go with that keyword instead of the standard one.

The keyword times are an input (``WORD@START-ENDs``; a speech recogniser can produce them). The search runs
once over the union of the standard and the keyword databases; each 8-frame step may only start in the
windows of the database that is active at its start time, so the pose continuity across the switch is the
search's own (pre-selection by the previous pose). Controls still apply, with their percentiles taken over
the standard database.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from anima.errors import InputError
from anima.gesture.knn import MatchDB

_RE = re.compile(r"^\s*([^@\s]+)\s*@\s*([0-9.]+)\s*-\s*([0-9.]+)\s*s?\s*$")


@dataclass
class Keyword:
    word: str
    start_s: float
    end_s: float


def parse_keyword(text: str) -> Keyword:
    m = _RE.match(text)
    if not m:
        raise InputError(f"cannot read keyword {text!r}: expected WORD@START-ENDs, e.g. 'yes@1.2-1.8s'")
    try:
        w, a, b = m.group(1).lower(), float(m.group(2)), float(m.group(3))
    except ValueError:
        raise InputError(f"cannot read the times of keyword {text!r}") from None
    if b <= a:
        raise InputError(f"keyword {text!r}: the end must be after the start")
    return Keyword(w, a, b)


def union(main: MatchDB, extra: dict[str, MatchDB]) -> tuple[MatchDB, np.ndarray, list[str]]:
    """One database holding ``main`` then each keyword database; per window the index of its part (0 = the
    standard database, i = ``names[i]``)."""
    names = ["<standard>"] + list(extra)
    dbs = [main] + [extra[n] for n in names[1:]]
    has_s = all(d.S is not None for d in dbs)
    if any(abs(d.fps - main.fps) > 1e-6 for d in dbs):
        raise InputError(f"keyword databases at {sorted({d.fps for d in dbs})} fps: all must be at one frame rate")
    u = MatchDB(
        np.concatenate([d.F for d in dbs]),
        np.concatenate([d.P for d in dbs]),
        np.concatenate([d.G for d in dbs]),
        sum((list(d.source) for d in dbs), []),
        np.concatenate([d.S for d in dbs]) if has_s else None,
        main.fps,
        None
        if all(d.rate is None for d in dbs)
        else np.concatenate([np.ones(d.M) if d.rate is None else d.rate for d in dbs]),
    )
    part = np.concatenate([np.full(d.M, i) for i, d in enumerate(dbs)])
    return u, part, names


def keyword_masks(
    db: MatchDB,
    part: np.ndarray,
    names: list[str],
    keywords: list[Keyword],
    n_steps: int,
    step_s: float,
    control_masks: list,
) -> tuple[list, list[str]]:
    """Per search step, the window-start mask: the active database's windows (a keyword's while it is spoken,
    else the standard one), intersected with the step's control mask when that leaves any candidate.
    Returns the masks and, per step, the name of the database used."""
    for kw in keywords:
        if kw.word not in names:
            raise InputError(
                f"keyword {kw.word!r} has no database: give --keyword-db {kw.word}=DATASET "
                f"(have: {', '.join(names[1:]) or 'none'})"
            )
    base = db.start_mask(None)
    out, used = [], []
    for k in range(n_steps):
        t = k * step_s
        active = [kw.word for kw in keywords if kw.start_s <= t < kw.end_s]
        p = names.index(active[0]) if active else 0
        m = base & (part == p)[:, None]
        c = control_masks[k] if control_masks else None
        if c is not None and (m & c).any():
            m = m & c
        out.append(m)
        used.append(names[p])
    return out, used
