"""A prompt -> a timeline of facial events: what the timeline method of ``anima text2face`` makes.

The vocabulary is the dataset's attribute detectors (``anima.dataset.attributes.ATTRIBUTES``) plus eight
emotions. A prompt is read clause by clause:

* clauses are cut at sequence words ("then", "after that", "next", "afterwards", "later", "finally",
  "followed by", ";", ". ") and at commas; events in one clause co-occur ("smiles and blinks"), and a clause
  that starts with "while" / "as" co-occurs with the one before it ("smiles while talking");
* each clause's events come from a phrase lexicon (paraphrases included: "grins", "beams", "furrows the
  brow", "drops the jaw", ...); a clause with no lexicon match is compared, when an encoder is given, with
  one prototype sentence per event (cosine >= ``PARAPHRASE_MIN``) and the match is reported back;
* counts ("once", "twice", "three times", "2 times", "a few times", "repeatedly"), intensity ("slightly",
  "a little", "broadly", "very", ...) and side ("left", "right": eyes, brows and smiles) attach to the
  clause's events;
* words that are neither vocabulary nor grammar are returned in ``Plan.unknown`` so the caller can say what
  was not understood.

Pure functions, no I/O: the encoder is passed in.
"""

from __future__ import annotations

import re
from dataclasses import asdict, dataclass, field, replace

from anima.core.events import BLINK, CONFLICTS, NEUTRAL, SCOPE, VOCABULARY
from anima.errors import InputError

# the vocabulary (anima.core.events): event -> its phrases (regular expressions, word-boundary anchored,
# matched on the lower-cased clause), in the vocabulary's order
LEXICON: dict[str, list[str]] = {n: e.phrases for n, e in VOCABULARY.items() if e.parsed}
EVENTS = tuple(n for n in LEXICON if n != "surprised" and VOCABULARY[n].unplaced is None)
SIDED = {n for n, e in VOCABULARY.items() if e.sided}
ONE_SIDED = {n: e.one_sided_words for n, e in VOCABULARY.items() if e.one_sided_words}
UNPLACED = {n: e.unplaced for n, e in VOCABULARY.items() if e.unplaced}
# one prototype sentence per event, for paraphrases the lexicon does not hold (sentence-encoder match)
PROTOTYPES = {n: e.prototype for n, e in VOCABULARY.items() if e.prototype}

PARAPHRASE_MIN = 0.55

COUNTS = [
    (r"\bonce\b", 1),
    (r"\btwice\b", 2),
    (r"\bthrice\b", 3),
    (r"\b(?:two|2)\s+times\b", 2),
    (r"\b(?:three|3)\s+times\b", 3),
    (r"\b(?:four|4)\s+times\b", 4),
    (r"\b(?:five|5)\s+times\b", 5),
    (r"\ba\s+couple\s+of\s+times\b", 2),
    (r"\b(?:a\s+few|several)\s+times\b", 3),
    (r"\b(?:repeatedly|rapidly|over\s+and\s+over|in\s+(?:quick\s+|rapid\s+)?succession)\b", 3),
    (r"\b(?:\d+)\s+times\b", None),  # a number the table does not name: read it
    # quantities before the event's noun: "a couple of quick blinks", "a few nods", "two winks"
    (r"\ba\s+couple\s+(?:of\s+)?(?=(?:\w+\s+){0,2}?(?:blinks|winks|nods|smiles|shakes|yawns)\b)", 2),
    (r"\ba\s+few\s+(?=(?:\w+\s+){0,2}?(?:blinks|winks|nods|smiles|shakes|yawns)\b)", 3),
    (r"\bseveral\s+(?=(?:\w+\s+){0,2}?(?:blinks|winks|nods|smiles|shakes|yawns)\b)", 4),
    (r"\b(?:two|2)\s+(?=(?:\w+\s+){0,2}?(?:blinks|winks|nods|smiles|shakes|yawns)\b)", 2),
    (r"\b(?:three|3)\s+(?=(?:\w+\s+){0,2}?(?:blinks|winks|nods|smiles|shakes|yawns)\b)", 3),
    (r"\b(?:four|4)\s+(?=(?:\w+\s+){0,2}?(?:blinks|winks|nods|smiles|shakes|yawns)\b)", 4),
    (r"\b(?:five|5)\s+(?=(?:\w+\s+){0,2}?(?:blinks|winks|nods|smiles|shakes|yawns)\b)", 5),
]
NEGATION = (
    r"\b(?:without|doesn't|does\s+not|don't|do\s+not|didn't|did\s+not|won't|never|no|not|isn't|aren't|stops|stop|"
    r"stopped|nor|neither|avoids|avoiding|refrains\s+from)\b"
)
"""Words that exclude the next event of their clause: "talks without smiling", "doesn't blink at all",
"no smile", "never looks up". The excluded event is not made, and the plan says so."""
SOFTER = (
    r"\b(?:a\s+(?:little|tiny|wee)\s+bit|a\s+(?:little|tiny)|a\s+bit|slight(?:ly)?|subtl[ey]|faint(?:ly)?|barely|"
    r"softly|gently|mildly|a\s+touch|small|tiny|hint\s+of|trace\s+of|hardly|stifl\w*|suppress\w*|restrain\w*|"
    r"somewhat|a\s+tad|kind\s+of|sort\s+of|half[- ]?hearted\w*|weakly|muted|lightly)\b"
)
SOFTEST = r"\b(?:slightest|faintest|smallest|tiniest|weakest|least|ghost\s+of)\b"
"""A superlative of softening ("the slightest smile", "the ghost of a smile"): :data:`FAINT` on its own."""
STRONGER = (
    r"\b(?:broadly|widely|very|really|extremely|strongly|hugely|big|wide|a\s+lot|hard|deeply|fully|intensely|so|"
    r"from\s+ear\s+to\s+ear)\b"
)
FAINT = 0.35
INTENSITY = [(SOFTER, 0.6), (SOFTEST, FAINT), (STRONGER, 1.4)]
"""Intensity as a dial: one softening word (:data:`SOFTER`) is 0.6, two of them ("a slight, faint
smile", "just a little bit, barely"), a strengthened one ("very slightly") or a superlative (:data:`SOFTEST`)
:data:`FAINT`; strengthening words alone 1.4; none 1. ``compose.STRENGTH`` turns each level into a peak range per
event, the same for the built-in library and a dataset."""
SEQUENCE = (
    r"\b(?:and\s+then|then|after\s+that|afterwards|afterward|next|later|finally|at\s+last|in\s+the\s+end|"
    r"followed\s+by|before\s+that)\b|[;.!?]"
)
CONCURRENT = r"^(?:while|as|whilst|during)\b"
GRAMMAR = set(
    """a an the this that these those her his their its one someone somebody person people man woman girl boy
    guy lady child kid he she they it is are am be being been was were has have had with at to of in on for
    and or but then also still keeps keep kept stays stay remains remain looks look looking seems appears face
    faces expression expressions eye eyes brow brows eyebrow eyebrows mouth jaw head lips lip while as during
    slowly quickly suddenly briefly moment short time long bit little very really slightly broadly left right
    both once twice thrice times time few several couple repeatedly again first begins starts start starting
    by up down out towards toward into from camera speaker actor actress presenter gently softly quite rather
    some something somewhat moderately over around just now after before finally next later afterwards lastly
    end last followed two three four five him them us me give gives giving side quick slow s throughout whole
    away breaks bursts ever there
    clip begin beginning meanwhile lastly only solely merely simply single brief briefly furtive furtively swift
    swiftly hint trace wee alone""".split()
)
SIDE = r"\b(left|right)\b"


@dataclass
class Event:
    """One requested event: ``attribute`` (a detector attribute or an emotion), how many times, how strong
    (1 = typical), which side (None = both), and its clause index (events of one clause co-occur)."""

    attribute: str
    count: int = 1
    intensity: float = 1.0
    side: str | None = None
    clause: int = 0
    words: str = ""


@dataclass
class Plan:
    """The parsed prompt: events in clause order, the words not understood, paraphrase matches, and notes."""

    text: str
    events: list[Event] = field(default_factory=list)
    excluded: list[str] = field(default_factory=list)
    unplaced: list[str] = field(default_factory=list)
    unknown: list[str] = field(default_factory=list)
    paraphrased: list[dict] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def n_clauses(self) -> int:
        return len({e.clause for e in self.events})

    def to_dict(self) -> dict:
        return {
            "text": self.text,
            "events": [asdict(e) for e in self.events],
            "excluded": self.excluded,
            "unplaced": self.unplaced,
            "unknown": self.unknown,
            "paraphrased": self.paraphrased,
            "notes": self.notes,
        }


MAX_COUNT = 50  # "blinks 10^12 times" is refused, not planned
MAX_PROMPT_CHARS = 2_000
"""The longest prompt read, in characters (whitespace runs count as one): ten times a long, detailed prompt of
ten events; the model's encoder reads about 1,000 of them anyway (MiniLM's 256 tokens). Parsing is linear in
the clauses, so this bounds the parse before it starts (``anima text2face``'s --help states it)."""
MAX_PROMPT_EVENTS = 100
"""The most events a prompt may name (each at most :data:`MAX_COUNT` times; the clip they make is bounded by
``anima.text2face.run.MAX_TIMELINE_FRAMES`` as well): more is refused, not planned."""


def _count(clause: str) -> int | None:
    for pat, n in COUNTS:
        m = re.search(pat, clause)
        if m:
            if n is None:
                digits = re.findall(r"\d+", m.group(0))[0]
                n = int(digits) if len(digits) <= 6 else MAX_COUNT + 1
            if not 1 <= n <= MAX_COUNT:
                raise InputError(f"{m.group(0).strip()!r}: anima plans an event 1 to {MAX_COUNT} times")
            return n
    return None


def _intensity(clause: str) -> float:
    soft = len(re.findall(SOFTER, clause))
    strong = bool(re.search(STRONGER, clause))
    if soft >= 2 or (soft and strong) or re.search(SOFTEST, clause):
        return FAINT
    return 0.6 if soft else 1.4 if strong else 1.0


def _clauses(text: str) -> list[tuple[str, bool]]:
    """``(clause, co-occurs with the previous one)`` in order."""
    out = []
    for part in re.split(SEQUENCE, text):
        for i, c in enumerate(p.strip() for p in part.split(",")):
            if not c:
                continue
            conc = bool(re.match(CONCURRENT, c)) and bool(out)
            # "X, while Y" or "X, talking": a bare participle after a comma accompanies the clause before it
            if i > 0 and re.match(r"^\w+ing\b", c) and out:
                conc = True
            out.append((c, conc))
    return out


def _direction(words: str, clause: str) -> str:
    """Where a gaze goes: the direction its words name, else what it looks at, else the clause's side."""
    m = re.search(r"\b(left|right|up|down)", words)
    if m:
        return m.group(1)
    if re.search(r"\b(?:floor|ground|feet|hands|lap|lower\w*|drop\w*|avert\w*)\b", words):
        return "down"
    if re.search(r"\b(?:sky|ceiling|rais\w*)\b", words):
        return "up"
    m = re.search(SIDE, clause)
    return m.group(1) if m else "left"


def _lexicon_matches(clause: str) -> list[tuple[int, str, tuple[int, int]]]:
    hits = []
    for ev, pats in LEXICON.items():
        for p in pats:
            for m in re.finditer(r"\b" + p + r"\b", clause):
                hits.append((m.start(), ev, m.span()))
    hits.sort()
    # a span inside another event's span is the same words (e.g. "says" covers the rest): keep the first
    kept: list[tuple[int, str, tuple[int, int]]] = []
    for h in hits:
        if any(h[2][0] >= k[2][0] and h[2][1] <= k[2][1] for k in kept) or any(k[1] == h[1] for k in kept):
            continue
        kept.append(h)
    return kept


def _bind_sides(clause: str, hits) -> dict[int, str]:
    """Each side word of a clause bound to the event it governs ("turns her head to the left and smiles" is a
    left turn and a plain smile): a side inside an event's words is that event's; one outside any
    goes to the nearest event before it that takes a side, else to the next one."""
    out: dict[int, str] = {}
    for m in re.finditer(SIDE, clause):
        at = m.start()
        k = next((k for k, h in enumerate(hits) if h[2][0] <= at < h[2][1]), None)
        if k is None:
            before = [k for k, h in enumerate(hits) if h[2][1] <= at and h[1] in SIDED]
            after = [k for k, h in enumerate(hits) if h[2][0] > at]
            k = before[-1] if before else (after[0] if after else None)
        if k is not None:
            out.setdefault(k, m.group(1))
    return out


ONLY_SIDE = (
    r"(?:and\s+|or\s+)?(?:back\s+)?(?:to\s+)?(?:the\s+)?(?:" + SCOPE + r")?(left|right|up|down)(?:wards?)?"
    r"(?:\s+(?:at|to|towards?|over|across)\s+.*)?"
)
"""A clause that only names a side or a direction ("..., then right", "..., then down at the floor")."""


def _takes_side(events: list[Event], side: str) -> bool:
    """Whether every event of the clause before takes ``side`` (up and down: only a gaze)."""
    if not events:
        return False
    if side in ("up", "down"):
        return all(e.attribute == "gaze" for e in events)
    return all(e.attribute in SIDED or e.attribute == "gaze" for e in events)


def _understood(clause: str) -> set[int]:
    """The character positions of ``clause`` that anima understands: every vocabulary word (repeated ones
    included), the counts, the intensity words and the negations."""
    used = set()
    for pats in LEXICON.values():
        for p in pats:
            for m in re.finditer(r"\b" + p + r"\b", clause):
                used.update(range(*m.span()))
    for pat, _ in COUNTS + INTENSITY + [(NEGATION, None), (r"\bat\s+all\b", None)]:
        for m in re.finditer(pat, clause):
            used.update(range(*m.span()))
    return used


def _drop_negated(clause: str, hits: list, plan: Plan) -> list:
    """``hits`` without the ones a negation excludes (the first event after it in the clause), which the plan
    lists as excluded."""
    negated = set()
    for m in re.finditer(NEGATION, clause):
        nxt = next((k for k, h in enumerate(hits) if h[0] >= m.end()), None)
        if nxt is not None:
            negated.add(nxt)
    for k in sorted(negated):
        plan.excluded.append(hits[k][1] + f" ('{clause[hits[k][2][0] : hits[k][2][1]]}')")
    return [h for k, h in enumerate(hits) if k not in negated]


def _add_events(plan: Plan, clause: str, hits: list, clause_i: int, count: int | None, inten: float) -> None:
    """The events of one clause's ``hits`` appended to the plan: a count attaches to the event it follows, each
    event's side bound from the clause's side words (a wink and a one-sided event default to the left; a gaze
    takes its direction); an event anima cannot place is noted instead."""
    sides = _bind_sides(clause, hits)
    for k, (_, ev, (a, b)) in enumerate(hits):
        # a count attaches to the event it follows (the last one before it in the clause)
        c = 1
        if count is not None:
            cm = max((m.start() for pat, _ in COUNTS for m in re.finditer(pat, clause)), default=-1)
            nxt = hits[k + 1][0] if k + 1 < len(hits) else len(clause) + 1
            if a <= cm < nxt or (len(hits) == 1):
                c = count
        if ev in UNPLACED:
            plan.notes.append(UNPLACED[ev])
            plan.unplaced.append(clause[a:b])
            continue
        sd = sides.get(k) if ev in SIDED else None
        if ev == BLINK and "wink" in clause[a:b] and sd is None:
            sd = "left"
        if ev in ONE_SIDED and sd is None and re.search(ONE_SIDED[ev], clause):
            sd = "left"
        if ev == "gaze":
            sd = _direction(clause[a:b], clause)
        plan.events.append(Event(ev, max(1, c), inten, sd, clause_i, clause[a:b]))


def _order_clauses(plan: Plan) -> None:
    """Within a clause, a neutral face gives way to the other events and an event that cannot happen with the
    ones before it follows them; the events sorted by clause, the clauses renumbered densely."""
    by_clause: dict[int, list[Event]] = {}
    for e in plan.events:
        by_clause.setdefault(e.clause, []).append(e)
    for c, evs in by_clause.items():
        if len(evs) > 1 and any(e.attribute == NEUTRAL for e in evs):
            plan.events = [e for e in plan.events if not (e.clause == c and e.attribute == NEUTRAL)]
            evs[:] = [e for e in evs if e.attribute != NEUTRAL]
        for i, e in enumerate(evs):
            if any({e.attribute, f.attribute} in CONFLICTS for f in evs[:i] if f.clause == c):
                plan.notes.append(f"'{e.words}' cannot happen together with the events before it: it follows them")
                e.clause = c + 0.5  # after its clause, before the next
    if plan.events:
        plan.events.sort(key=lambda e: e.clause)
        # renumber clauses densely in order
        order = {c: i for i, c in enumerate(dict.fromkeys(e.clause for e in plan.events))}
        for e in plan.events:
            e.clause = order[e.clause]
    else:
        plan.notes.append("no facial event recognised: a neutral face is returned")


def parse(prompt: str, encoder=None) -> Plan:
    """The events a prompt asks for (see the module docstring). ``encoder``: an object with ``encode(list
    of str) -> [N, d]`` unit vectors, used only for clauses the lexicon does not cover."""
    text = " ".join(prompt.strip().split())
    if len(text) > MAX_PROMPT_CHARS:
        raise InputError(
            f"the prompt has {len(text):,} characters: anima reads at most {MAX_PROMPT_CHARS:,} "
            f"(and {MAX_PROMPT_EVENTS} events)"
        )
    plan = Plan(text)
    low = text.lower().replace("’", "'")
    proto = None
    clause_i = -1
    pending = ""  # intensity words in a clause of their own before the events they grade ("a slight, faint smile")
    last: tuple[str, list[Event]] = ("", [])  # the previous clause with events, and its events
    for clause, conc in _clauses(low):
        if not conc or clause_i < 0:
            clause_i += 1
        hits = _lexicon_matches(clause)
        # "surprised" the emotion and "surprise" the event are one thing; a neutral face while talking is talk
        names = [h[1] for h in hits]
        if NEUTRAL in names and len(names) > 1:
            hits = [h for h in hits if h[1] != NEUTRAL]
        used = _understood(clause)
        hits = _drop_negated(clause, hits, plan)
        rest = "".join(ch if i not in used else " " for i, ch in enumerate(clause))
        words = [w for w in re.findall(r"[a-z']+", rest) if w not in GRAMMAR and not w.isdigit()]
        if not hits and encoder is not None and words:
            if proto is None:
                keys = list(PROTOTYPES)
                proto = (keys, encoder.encode([PROTOTYPES[k] for k in keys]))
            v = encoder.encode([clause])[0]
            sims = proto[1] @ v
            j = int(sims.argmax())
            if float(sims[j]) >= PARAPHRASE_MIN:
                hits = [(0, proto[0][j], (0, len(clause)))]
                plan.paraphrased.append({"words": clause, "as": proto[0][j], "cosine": round(float(sims[j]), 3)})
                words = []
        only_side = re.fullmatch(ONLY_SIDE, clause.strip())
        if not hits and only_side and _takes_side(last[1], only_side.group(1)):
            # "glances left, then right", "looks up at the sky, then down at the floor": the clause's verb is the
            # one before it, with this side or direction
            for e in last[1]:
                side = _direction(clause, clause) if e.attribute == "gaze" else only_side.group(1)
                plan.events.append(replace(e, side=side, clause=clause_i, words=clause.strip()))
            last = (clause, plan.events[-len(last[1]) :])
            continue
        if words:
            plan.unknown.extend(words)
        if not hits:
            if any(re.search(p, clause) for p, _ in INTENSITY):  # it grades the events next to it
                if last[1]:
                    text = last[0] + " " + clause
                    for e in last[1]:
                        e.intensity = _intensity(text)
                    last = (text, last[1])
                else:
                    pending += " " + clause
            continue
        count = _count(clause)
        inten = _intensity(pending + " " + clause)
        pending = ""
        n_before = len(plan.events)
        _add_events(plan, clause, hits, clause_i, count, inten)
        last = (clause, plan.events[n_before:])
    if len(plan.events) > MAX_PROMPT_EVENTS:
        raise InputError(
            f"the prompt names {len(plan.events)} events: anima plans at most {MAX_PROMPT_EVENTS} "
            f"(each up to {MAX_COUNT} times)"
        )
    _order_clauses(plan)
    if plan.excluded:
        plan.notes.append("not made, as the prompt says: " + ", ".join(plan.excluded))
    if plan.unknown:
        plan.notes.append("not understood: " + ", ".join(dict.fromkeys(plan.unknown)))
    return plan
