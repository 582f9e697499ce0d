"""A prompt -> a timeline of facial events (issue 19): what the timeline method of ``anima text2face`` makes.

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

from anima.errors import InputError

EMOTIONS = ("happy", "sad", "angry", "disgusted", "fearful", "surprised", "contempt", "neutral")

# event -> regular expressions (word-boundary anchored, matched on the lower-cased clause)
_SCOPE = r"(?:(?:only|just|solely|merely|simply)\s+)?"
"""Words that restrict an event ("raises only her left eyebrow"): read with the words they govern, whose side
the clause names."""
_OBJ = _SCOPE + r"(?:(?:the|her|his|their|its|one|an?)\s+)?"
_LOOKV = (
    r"(?:looks?|looking|looked|glanc\w*|peeks?|peeking|peeked|peers?|peering|peered|peeps?|peeping|peeped|"
    r"glimps\w*|stares?|staring|stared|eyes|eyeing|eyed|checks?|checking|checked)"
)
"""Verbs of looking: a short look to one side (:data:`_ASIDE`) is a turn of the head."""
_ASIDE = (
    r"(?:(?:to\s+(?:the\s+|one\s+|her\s+|his\s+|their\s+)?)?(?:left|right|away|aside|sideways|side)\b|"
    r"(?:back\s+)?over\s+(?:(?:her|his|their|the|one)\s+)?(?:left\s+|right\s+)?shoulder)"
)
_LOOKN = r"(?:glance|look|peek|peep|glimpse|sideways\s+look|look\s+around)s?"
"""Nouns of looking, after a verb that gives one ("casts a glance", "sneaks a peek", "takes a quick look")."""
_DIR = r"(?:left|right|up|upwards?|down|downwards?)"
LEXICON: dict[str, list[str]] = {
    "blink": [r"blink\w*", r"bats?\s+" + _OBJ + r"(?:eye)?lash\w*", r"wink\w*", r"flutter\w*\s+" + _OBJ + r"eyes?"],
    "smile": [r"smil\w*", r"grin\w*", r"beam\w*", r"smirk\w*"],
    "frown": [
        r"frown\w*",
        r"scowl\w*",
        r"furrow\w*(?:\s+" + _OBJ + r"brows?)?",
        r"knit\w*\s+" + _OBJ + r"brows?",
        r"lower\w*\s+" + _OBJ + r"(?:eye)?brows?",
    ],
    "squint": [r"squint\w*", r"narrow\w*\s+" + _OBJ + r"eyes?"],
    "raise eyebrows": [
        r"rais\w*\s+" + _OBJ + r"(?:left\s+|right\s+)?(?:eye)?brows?",
        r"lift\w*\s+" + _OBJ + r"(?:left\s+|right\s+)?(?:eye)?brows?",
        r"(?:eye)?brows?\s+(?:go(?:es)?\s+|shoot\s+|are\s+)?up",
        r"arch\w*\s+" + _OBJ + r"(?:eye)?brows?",
    ],
    "surprise": [
        r"surpris\w*",
        r"astonish\w*",
        r"amazed",
        r"amazement",
        r"shock\w*",
        r"startl\w*",
        r"gasp\w*",
        r"stunned",
    ],
    "mouth open": [
        r"opens?\s+" + _OBJ + r"mouth(?:\s+wide)?",
        r"opening\s+" + _OBJ + r"mouth",
        r"mouth\s+(?:is\s+|falls\s+|drops\s+|hangs\s+)?(?:wide\s+)?open",
        r"drops?\s+" + _OBJ + r"jaw",
        r"jaw\s+drops?",
        r"gap\w*",
    ],
    "yawn": [r"yawn\w*"],
    "talk": [
        r"talk\w*",
        r"speak\w*",
        r"says?\b.*",
        r"saying\b.*",
        r"chat\w*",
        r"convers\w*",
        r"lectur\w*",
        r"tells?\b.*",
        r"explain\w*",
        r"reads?\s+aloud",
        r"mutter\w*",
        r"murmur\w*",
        r"mumbl\w*",
        r"whisper\w*",
        r"rambl\w*",
    ],
    "nod": [r"nod\w*", r"agrees?", r"bob\w*\s+" + _OBJ + r"head"],
    "shake head": [
        r"shak\w*\s+" + _OBJ + r"head",
        r"head\s+shak\w*",
        r"shakes?\s+no",
        r"disagrees?",
        r"shak(?:es|ing)\b",
    ],
    "turn": [
        r"turn\w*\s+" + _OBJ + r"(?:head|face)",
        r"cran\w*\s+" + _OBJ + r"neck",
        r"turn\w*\s+(?:to\s+the\s+)?(?:left|right|away|aside|sideways)",
        _LOOKV + r"\s+(?:\w+\s+)?" + _ASIDE,
        r"(?:takes?|taking|took|casts?|casting|cast|steals?|stealing|stole|shoots?|shooting|shot|throws?|throwing|"
        r"threw|sneaks?|sneaking|snuck|gives?|giving|gave|darts?|darting|darted)\s+(?:a\s+|an\s+)?(?:\w+\s+)?"
        + _LOOKN
        + r"(?:\s+(?:\w+\s+)?"
        + _ASIDE
        + r")?",
        r"side(?:long|ways)?\s+(?:glance|look)s?",
        r"(?:whip|swivel|jerk|snap|twist|swing|swung)\w*\s+" + _OBJ + r"head(?:\s+(?:a?round|" + _ASIDE + r"))?",
    ],
    # emotions (each synthesised by its action units, see compose.EMOTION_AUS)
    "happy": [r"happ(?:y|ily|iness)", r"joy\w*", r"cheerful\w*", r"glad", r"delight\w*", r"pleased"],
    "sad": [
        r"sad\w*",
        r"unhappy",
        r"sorrow\w*",
        r"gloom\w*",
        r"upset",
        r"depress\w*",
        r"miserable",
        r"grie\w*",
        r"tearful",
    ],
    "angry": [
        r"angr\w*",
        r"anger",
        r"mad",
        r"furious\w*",
        r"annoy\w*",
        r"irritat\w*",
        r"rage\w*",
        r"enrag\w*",
        r"cross",
    ],
    "disgusted": [r"disgust\w*", r"grossed\s+out", r"revolt\w*", r"repuls\w*", r"sick(?:ened)?"],
    "fearful": [r"fear\w*", r"afraid", r"scar\w*", r"frighten\w*", r"terrif\w*", r"anxious\w*", r"nervous\w*"],
    "surprised": [],  # "surprised" reads as the surprise event (the detectors' word)
    "contempt": [r"contempt\w*", r"scorn\w*", r"disdain\w*", r"sneer\w*"],
    "close eyes": [
        r"clos\w*\s+" + _OBJ + r"eyes",
        r"eyes\s+(?:are\s+|stay\s+|kept\s+)?(?:closed|shut)",
        r"shut\w*\s+" + _OBJ + r"eyes",
    ],
    # keyframed events (anima.text2face.poses): no detector labels them, so they are made, not copied
    "gaze": [
        r"eyes?\s+(?:\w+\s+)?(?:dart\w*|shift\w*|mov\w*|flick\w*|drift\w*|go(?:es)?|turn\w*|slid\w*|wander\w*)\s+"
        r"(?:to\s+(?:the\s+)?)?" + _DIR,
        r"gaz\w*\s+(?:\w+\s+)?(?:to\s+(?:the\s+)?)?" + _DIR,
        r"(?:shifts?|shifting|moves?|moving|drops?|dropping|lowers?|lowering|raises?|raising|averts?|averting)\s+"
        + _OBJ
        + r"(?:gaze|eyes)(?:\s+(?:to\s+(?:the\s+)?)?"
        + _DIR
        + r")?",
        r"(?:looks?|looking|glanc\w*|peers?|peering|peeks?|peeking|stares?|staring)\s+(?:straight\s+)?(?:up|down)"
        r"(?:wards?)?",
        r"looks?\s+(?:to\s+(?:the\s+)?)?(?:left|right)\s+with\s+" + _OBJ + r"eyes",
        r"looks?\s+(?:down\s+|up\s+)?at\s+(?:the\s+)?(?:floor|ground|sky|ceiling|(?:her|his|their)\s+(?:feet|hands|lap))",
        r"side[- ]?eye\w*",
    ],
    "roll eyes": [r"roll\w*\s+" + _OBJ + r"eyes", r"eye[- ]?roll\w*"],
    "puff cheeks": [
        r"puff\w*\s+(?:up\s+|out\s+)?" + _OBJ + r"(?:left\s+|right\s+)?cheeks?(?:\s+out)?",
        r"cheeks?\s+(?:are\s+)?puff\w*(?:\s+out)?",
        r"blow\w*\s+(?:out\s+|up\s+)?" + _OBJ + r"cheeks(?:\s+out)?",
        r"puff\w*\s+(?:up|out)",
    ],
    "pout": [r"pout\w*", r"sulk\w*", r"push\w*\s+(?:out\s+)?" + _OBJ + r"(?:lower\s+)?lip(?:\s+out)?"],
    "pucker": [r"pucker\w*", r"purs\w*\s+" + _OBJ + r"lips", r"(?:blows?|blowing)\s+a\s+kiss", r"kiss\w*"],
    "press lips": [
        r"press\w*\s+" + _OBJ + r"lips(?:\s+together)?",
        r"tighten\w*\s+" + _OBJ + r"(?:lips|mouth)",
        r"lips\s+(?:are\s+)?(?:pressed|tight\w*|thin\w*)(?:\s+together)?",
        r"compress\w*\s+" + _OBJ + r"lips",
        r"(?:thin|tight)\s+lips",
    ],
    "roll lips": [
        r"(?:rolls?|rolling|sucks?|sucking|tucks?|tucking|pulls?|pulling)\s+(?:in\s+)?" + _OBJ + r"lips(?:\s+in)?",
        r"bit\w*\s+" + _OBJ + r"(?:lower\s+|upper\s+)?lip",
    ],
    "shrug": [r"shrug\w*"],
    "grimace": [r"grimac\w*", r"stretch\w*\s+" + _OBJ + r"lips", r"cring\w*", r"clench\w*\s+" + _OBJ + r"teeth"],
    "funnel": [r"funnel\w*", r"o[- ]shape\w*", r"whistl\w*", r"(?:mouths?|forms?|makes?)\s+an?\s+[\"']?oh?\b[\"']?"],
    "bare teeth": [r"bar\w*\s+" + _OBJ + r"teeth", r"shows?\s+" + _OBJ + r"teeth", r"snarl\w*"],
    "wrinkle nose": [
        r"wrinkl\w*\s+" + _OBJ + r"nose",
        r"nose\s+wrinkl\w*",
        r"scrunch\w*\s+(?:up\s+)?" + _OBJ + r"(?:nose|face)(?:\s+up)?",
    ],
    "widen eyes": [
        r"widen\w*\s+" + _OBJ + r"eyes",
        r"eyes\s+(?:go\s+|are\s+|grow\s+)?wide",
        r"wide[- ]eyed",
        r"opens?\s+" + _OBJ + r"eyes\s+wide",
    ],
    "jaw forward": [
        r"(?:juts?|jutting|thrusts?|pushes|pushing|sticks?)\s+(?:out\s+)?"
        + _OBJ
        + r"(?:jaw|chin)(?:\s+(?:forward|out))?"
    ],
    "jaw side": [
        r"(?:moves?|shifts?|slides?|pushes)\s+" + _OBJ + r"jaw\s+(?:to\s+(?:the\s+)?)?(?:left|right|sideways)"
    ],
    "mouth side": [
        r"(?:moves?|shifts?|pulls?|twists?|purses?)\s+"
        + _OBJ
        + r"mouth\s+(?:to\s+(?:the\s+|one\s+)?)?(?:left|right|side)",
        r"twist\w*\s+" + _OBJ + r"mouth",
    ],
    "tongue": [
        r"(?:sticks?\s+(?:out\s+)?" + _OBJ + r")?tongue\w*(?:\s+out)?"
    ],  # reported: the face model has no tongue
    "neutral": [
        r"neutral(?:\s+face|\s+expression)?",
        r"calm\w*",
        r"expressionless",
        r"blank\s+(?:face|expression|stare)",
        r"straight\s+face",
        r"(?:stays?|keeps?|remains?|sits?)\s+still",
        r"relax\w*",
        r"poker\s+face",
    ],
}
EVENTS = tuple(k for k in LEXICON if k not in ("surprised", "tongue"))
SIDED = {"blink", "raise eyebrows", "smile", "squint", "turn", "puff cheeks", "press lips", "bare teeth",
         "wrinkle nose", "jaw side", "mouth side"}  # fmt: skip
ONE_SIDED = {  # words that make an event one-sided when no side is named (the left, by convention)
    "smile": r"\b(?:smirk\w*|half[- ]smil\w*|lopsided|crooked|one[- ]sided|half\s+of)\b",
    "raise eyebrows": r"\b(?:one|an|a\s+single|single)\s+(?:eye)?brow\b",
}
UNPLACED = {"tongue": "tongue: the face model has no tongue (ICT-FaceKit's 53 expressions), not made"}
# One prototype sentence per event, for paraphrases the lexicon does not hold (sentence-encoder match).
PROTOTYPES = {
    "blink": "a person blinks their eyes",
    "smile": "a person smiles",
    "frown": "a person frowns with lowered eyebrows",
    "squint": "a person squints their eyes",
    "raise eyebrows": "a person raises their eyebrows",
    "surprise": "a person looks surprised",
    "mouth open": "a person opens their mouth",
    "yawn": "a person yawns",
    "talk": "a person talks",
    "nod": "a person nods their head",
    "shake head": "a person shakes their head",
    "turn": "a person turns their head to the side",
    "happy": "a person looks happy",
    "sad": "a person looks sad",
    "angry": "a person looks angry",
    "disgusted": "a person looks disgusted",
    "fearful": "a person looks afraid",
    "contempt": "a person looks at someone with contempt",
    "close eyes": "a person closes their eyes",
    "neutral": "a person keeps a neutral face",
    "gaze": "a person looks up with their eyes",
    "roll eyes": "a person rolls their eyes",
    "puff cheeks": "a person puffs out their cheeks",
    "pout": "a person pouts",
    "press lips": "a person presses their lips together",
    "grimace": "a person grimaces",
    "wrinkle nose": "a person wrinkles their nose",
    "widen eyes": "a person widens their eyes",
}
# events that cannot happen at the same moment: the second is moved to follow the first (with a note)
CONFLICTS = [
    {"close eyes", "blink"},
    {"close eyes", "squint"},
    {"close eyes", "surprise"},
    {"yawn", "talk"},
    {"nod", "shake head"},
    {"smile", "sad"},
    {"happy", "sad"},
    {"happy", "angry"},
    {"smile", "angry"},
]
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
    (r"\brepeatedly\b", 3),
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
    r"softly|gently|mildly|a\s+touch|small|tiny|hint\s+of|trace\s+of|hardly|stifl\w*|suppress\w*|restrain\w*)\b"
)
STRONGER = (
    r"\b(?:broadly|widely|very|really|extremely|strongly|hugely|big|wide|a\s+lot|hard|deeply|fully|intensely|so|"
    r"from\s+ear\s+to\s+ear)\b"
)
INTENSITY = [(SOFTER, 0.6), (STRONGER, 1.4)]
FAINT = 0.35
"""Intensity as a dial (issue 50): one softening word (:data:`SOFTER`) is 0.6, two of them ("a slight, faint
smile", "just a little bit, barely") or a strengthened one ("very slightly") :data:`FAINT`; strengthening
words alone 1.4; none 1. ``compose.STRENGTH`` turns each level into a peak range per event, the same for the
built-in library and a dataset."""
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
    swiftly hint trace wee""".split()
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
    if soft >= 2 or (soft and strong):
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
    """Each side word of a clause bound to the event it governs (issue 50: "turns her head to the left and
    smiles" is a left turn and a plain smile): a side inside an event's words is that event's; one outside any
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


def parse(prompt: str, encoder=None) -> Plan:
    """The events a prompt asks for (see the module docstring). ``encoder``: an object with ``encode(list
    of str) -> [N, d]`` unit vectors, used only for clauses the lexicon does not cover."""
    text = " ".join(prompt.strip().split())
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
        if "neutral" in names and len(names) > 1:
            hits = [h for h in hits if h[1] != "neutral"]
        used = set()
        for pats in LEXICON.values():  # every vocabulary word is understood, repeated ones included
            for p in pats:
                for m in re.finditer(r"\b" + p + r"\b", clause):
                    used.update(range(*m.span()))
        for pat, _ in COUNTS + INTENSITY + [(NEGATION, None), (r"\bat\s+all\b", None)]:
            for m in re.finditer(pat, clause):
                used.update(range(*m.span()))
        # a negation excludes the first event after it in the clause
        negated = set()
        for m in re.finditer(NEGATION, clause):
            nxt = next((k for k, h in enumerate(hits) if h[0] >= m.end()), None)
            if nxt is not None:
                negated.add(nxt)
        for k in sorted(negated):
            plan.excluded.append(hits[k][1] + f" ('{clause[hits[k][2][0] : hits[k][2][1]]}')")
        hits = [h for k, h in enumerate(hits) if k not in negated]
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
        if words:
            plan.unknown.extend(words)
        only_side = re.fullmatch(
            r"(?:and\s+|or\s+)?(?:to\s+)?(?:the\s+)?(?:" + _SCOPE + r")?(left|right)", clause.strip()
        )
        if not hits and only_side and last[1] and all(e.attribute in SIDED for e in last[1]):
            # "glances left, then right": the clause's verb is the one before it, with this side
            for e in last[1]:
                plan.events.append(replace(e, side=only_side.group(1), clause=clause_i, words=clause.strip()))
            last = (clause, plan.events[-len(last[1]) :])
            continue
        if not hits:
            if re.search(SOFTER, clause) or re.search(STRONGER, clause):  # it grades the events next to it
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
            if ev == "blink" and "wink" in clause[a:b] and sd is None:
                sd = "left"
            if ev in ONE_SIDED and sd is None and re.search(ONE_SIDED[ev], clause):
                sd = "left"
            if ev == "gaze":
                sd = _direction(clause[a:b], clause)
            plan.events.append(Event(ev, max(1, c), inten, sd, clause_i, clause[a:b]))
        last = (clause, plan.events[n_before:])
    by_clause: dict[int, list[Event]] = {}
    for e in plan.events:
        by_clause.setdefault(e.clause, []).append(e)
    for c, evs in by_clause.items():
        if len(evs) > 1 and any(e.attribute == "neutral" for e in evs):
            plan.events = [e for e in plan.events if not (e.clause == c and e.attribute == "neutral")]
            evs[:] = [e for e in evs if e.attribute != "neutral"]
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
    if plan.excluded:
        plan.notes.append("not made, as the prompt says: " + ", ".join(plan.excluded))
    if plan.unknown:
        plan.notes.append("not understood: " + ", ".join(dict.fromkeys(plan.unknown)))
    return plan
