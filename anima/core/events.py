"""The facial-event vocabulary, declared once: every event a prompt can ask for, a detector can
label or a description can say, with what each part of anima needs to know about it.

One :class:`Event` per event: the prompt parser's phrases (regular expressions, word-boundary anchored, matched
on the lower-cased clause) and prototype sentence (:mod:`anima.text2face.prompt`), the words a description uses
(:mod:`anima.dataset.describe`), whether the dataset's detectors label it (:mod:`anima.dataset.attributes`; in
their order), and how the timeline method makes it (:mod:`anima.text2face.compose`): the channels it moves,
its side, its hold, the strength range of each stated intensity. Events are named by the constants below
(``RAISE_BROWS`` ...) where code refers to one.

The independent judge (:mod:`anima.eval.text2face.judge`) keeps its own list and rules: it must not share the
generator's.

Pure data, no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass, field

# the events the dataset's detectors label (anima.dataset.attributes), plus two states; code names them so
BLINK, SMILE, FROWN, SQUINT, RAISE_BROWS = "blink", "smile", "frown", "squint", "raise eyebrows"
SURPRISE, MOUTH_OPEN, YAWN, TALK = "surprise", "mouth open", "yawn", "talk"
NOD, SHAKE_HEAD, TURN = "nod", "shake head", "turn"
CLOSE_EYES, NEUTRAL = "close eyes", "neutral"

HEAD = "head"
"""The channel name of the head's rotation (nod, shake, turn)."""
LIPS = (
    "jawOpen", "mouthClose", "mouthFunnel", "mouthPucker", "mouthLowerDown_L", "mouthLowerDown_R", "mouthUpperUp_L",
    "mouthUpperUp_R", "mouthPress_L", "mouthPress_R", "mouthStretch_L", "mouthStretch_R", "mouthRollLower",
    "mouthRollUpper", "mouthShrugLower", "mouthShrugUpper",
)  # fmt: skip
"""The ARKit channels of the lips and jaw (an event on the mouth moves all of them)."""


def both_sides(*stems: str) -> tuple[str, ...]:
    return tuple(f"{s}_{k}" for s in stems for k in "LR")


@dataclass(frozen=True)
class Event:
    """One facial event and what the parser, the detectors, the descriptions and the composer know of it."""

    name: str
    phrases: list[str] = field(default_factory=list)
    """The prompt parser's regular expressions (empty: read as another event, e.g. "surprised")."""
    parsed: bool = True
    """Whether the prompt parser knows it (False: only imported annotations and descriptions use it)."""
    prototype: str | None = None
    """A sentence for paraphrases the phrases do not hold (a sentence encoder's nearest)."""
    verbs: tuple[str, str] | None = None
    """A description's verb phrase (third person singular, base form); None: the name plus "s"."""
    synonyms: tuple[tuple[str, str], ...] = ()
    """Other verb phrases a description may use (each read back by the parser)."""
    detected: bool = False
    """Whether the dataset's detectors label it (a captured segment can be drawn for it)."""
    emotion: bool = False
    action_units: dict[str, float] | None = None
    """An emotion as ARKit weights (EMFACS prototypes): positive pull towards the channel, negative away."""
    channels: tuple[str, ...] = ()
    """The channels a captured segment of it contributes (the rest of the segment is left out)."""
    main: tuple[str, ...] = ()
    """The channels whose peak sets its strength (empty: every channel)."""
    peak_of_mean: bool = False
    """The peak taken on the mean of the main channels, not the largest."""
    sided: bool = False
    """Whether "left" / "right" in its clause applies to it."""
    one_sided_words: str | None = None
    """Words that make it one-sided when no side is named (the left, by convention)."""
    one_sided_pose: str | None = None
    """The keyframed pose (anima.text2face.poses) that makes its one-sided version."""
    symmetric: bool = False
    """Made alike on both sides when no side is named."""
    holdable: bool = False
    """Can be held ("for a while"): its segment's middle stretches."""
    max_hold_s: float | None = None
    """The longest it may be held before it reads as another event (an open mouth held 1 s is a yawn)."""
    strength: dict[float, tuple[float, float]] | None = None
    """Stated intensity -> the range its peak is brought into (None: the composer's default ranges)."""
    unplaced: str | None = None
    """Why it is understood but not made (reported back to the user)."""


SCOPE = r"(?:(?:only|just|solely|merely|simply)\s+)?"
"""Words that restrict an event ("raises only her left eyebrow"): read with the words they govern, whose side
the clause names."""
_OBJ = SCOPE + r"(?:(?:the|her|his|their|its|one|an?)\s+)?"
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

_EVENTS = [
    Event(
        BLINK,
        one_sided_pose="wink",
        detected=True,
        phrases=[r"blink\w*", r"bats?\s+" + _OBJ + r"(?:eye)?lash\w*", r"wink\w*", r"flutter\w*\s+" + _OBJ + r"eyes?"],
        prototype="a person blinks their eyes",
        verbs=("blinks", BLINK),
        channels=both_sides("eyeBlink"),
        sided=True,
        symmetric=True,
        strength={0.35: (0.4, 0.5), 0.6: (0.5, 0.6), 1.0: (0.9, 0.95), 1.4: (0.95, 1.0)},
    ),
    Event(
        SMILE,
        one_sided_pose="half smile",
        detected=True,
        phrases=[r"smil\w*", r"grin\w*", r"beam\w*", r"smirk\w*"],
        prototype="a person smiles",
        verbs=("smiles", SMILE),
        synonyms=(("smiles", SMILE), ("grins", "grin")),
        channels=both_sides("mouthSmile", "cheekSquint", "mouthDimple"),
        main=("mouthSmile_L", "mouthSmile_R"),
        sided=True,
        one_sided_words="\\b(?:smirk\\w*|half[- ]smil\\w*|lopsided|crooked|one[- ]sided|half\\s+of)\\b",
        symmetric=True,
        holdable=True,
        strength={0.35: (0.25, 0.33), 0.6: (0.55, 0.65), 1.0: (0.7, 0.9), 1.4: (0.9, 1.0)},
    ),
    Event(
        FROWN,
        detected=True,
        phrases=[
            r"frown\w*",
            r"scowl\w*",
            r"glower\w*",
            r"glar(?:e|es|ed|ing)\b",
            r"furrow\w*(?:\s+" + _OBJ + r"brows?)?",
            r"knit\w*\s+" + _OBJ + r"brows?",
            r"lower\w*\s+" + _OBJ + r"(?:eye)?brows?",
        ],
        prototype="a person frowns with lowered eyebrows",
        verbs=("frowns", FROWN),
        synonyms=(("frowns", FROWN), ("furrows the brow", "furrow the brow")),
        channels=both_sides("browDown", "noseSneer"),
        main=("browDown_L", "browDown_R"),
        symmetric=True,
        holdable=True,
        strength={0.35: (0.6, 0.7), 0.6: (0.8, 0.9), 1.0: (0.9, 1.0), 1.4: (1.0, 1.0)},
    ),
    Event(
        SQUINT,
        detected=True,
        phrases=[r"squint\w*", r"narrow\w*\s+" + _OBJ + r"eyes?"],
        prototype="a person squints their eyes",
        verbs=("squints", SQUINT),
        synonyms=(("squints", SQUINT), ("narrows the eyes", "narrow the eyes")),
        channels=both_sides("eyeSquint", "cheekSquint"),
        sided=True,
        symmetric=True,
        holdable=True,
    ),
    Event(
        RAISE_BROWS,
        one_sided_pose="brow raise",
        detected=True,
        phrases=[
            r"rais\w*\s+" + _OBJ + r"(?:left\s+|right\s+)?(?:eye)?brows?",
            r"lift\w*\s+" + _OBJ + r"(?:left\s+|right\s+)?(?:eye)?brows?",
            r"(?:eye)?brows?\s+(?:go(?:es)?\s+|shoot\s+|are\s+)?up",
            r"arch\w*\s+" + _OBJ + r"(?:left\s+|right\s+)?(?:eye)?brows?",
        ],
        prototype="a person raises their eyebrows",
        verbs=("raises the eyebrows", "raise the eyebrows"),
        synonyms=(("raises the eyebrows", "raise the eyebrows"), ("lifts the eyebrows", "lift the eyebrows")),
        channels=both_sides("browInnerUp", "browOuterUp"),
        sided=True,
        one_sided_words="\\b(?:one|an|a\\s+single|single)\\s+(?:eye)?brow\\b",
        symmetric=True,
        holdable=True,
        max_hold_s=0.7,
        strength={0.35: (0.35, 0.45), 0.6: (0.5, 0.65), 1.0: (0.7, 0.9), 1.4: (0.9, 1.0)},
        peak_of_mean=True,
    ),
    Event(
        SURPRISE,
        detected=True,
        phrases=[
            r"surpris\w*",
            r"astonish\w*",
            r"amazed",
            r"amazement",
            r"shock\w*",
            r"startl\w*",
            r"gasp\w*",
            r"stunned",
        ],
        prototype="a person looks surprised",
        verbs=("looks surprised", "look surprised"),
        channels=both_sides("browInnerUp", "browOuterUp", "eyeWide") + LIPS,
        main=("browInnerUp_L", "browInnerUp_R", "browOuterUp_L", "browOuterUp_R"),
        holdable=True,
        max_hold_s=0.6,
    ),
    Event(
        MOUTH_OPEN,
        detected=True,
        phrases=[
            r"opens?\s+" + _OBJ + r"mouth(?:\s+wide)?",
            r"opening\s+" + _OBJ + r"mouth",
            r"mouth\s+(?:is\s+|falls\s+|drops\s+|hangs\s+)?(?:wide\s+)?open",
            r"drops?\s+" + _OBJ + r"jaw",
            r"jaw\s+drops?",
            r"gap\w*",
        ],
        prototype="a person opens their mouth",
        verbs=("opens the mouth", "open the mouth"),
        synonyms=(("opens the mouth", "open the mouth"), ("drops the jaw", "drop the jaw")),
        channels=LIPS,
        main=("jawOpen",),
        holdable=True,
        max_hold_s=0.6,
        strength={0.35: (0.2, 0.28), 0.6: (0.32, 0.36), 1.0: (0.36, 0.44), 1.4: (0.44, 0.6)},
    ),
    Event(
        YAWN,
        detected=True,
        phrases=[r"yawn\w*"],
        prototype="a person yawns",
        verbs=("yawns", YAWN),
        channels=LIPS + both_sides("eyeSquint"),
        main=("jawOpen",),
        strength={0.35: (0.4, 0.5), 0.6: (0.5, 0.6), 1.0: (0.6, 0.8), 1.4: (0.8, 1.0)},
    ),
    Event(
        TALK,
        detected=True,
        phrases=[
            r"talk\w*",
            r"speak\w*",
            r"says?\b.*",
            r"saying\b.*",
            r"chat\w*",
            r"convers\w*",
            r"lectur\w*",
            r"tell(?:s|ing)?\b.*",
            r"explain\w*",
            r"read(?:s|ing)?\s+(?:\w+\s+)?(?:aloud|out\s+loud|the\s+news|a\s+(?:story|poem|speech|script|passage))",
            r"speech(?:es)?",
            r"narrat\w*",
            r"recit\w*",
            r"announc\w*",
            r"discuss\w*",
            r"describ\w*",
            r"gossip\w*",
            r"babbl\w*",
            r"jabber\w*",
            r"prattl\w*",
            r"interview(?:s|ed|ing)\b",
            r"answer\w*",
            r"ask(?:s|ed|ing)?\s+(?:\w+\s+)?questions?",
            r"pronounc\w*",
            r"present(?:s|ed|ing)\b",
            r"mutter\w*",
            r"murmur\w*",
            r"mumbl\w*",
            r"whisper\w*",
            r"rambl\w*",
        ],
        prototype="a person talks",
        verbs=("talks", TALK),
        synonyms=(("talks", TALK), ("speaks", "speak")),
        channels=LIPS,
    ),
    Event(
        NOD,
        detected=True,
        phrases=[r"nod\w*", r"agrees?", r"bob\w*\s+" + _OBJ + r"head"],
        prototype="a person nods their head",
        verbs=("nods", NOD),
        channels=(HEAD,),
    ),
    Event(
        SHAKE_HEAD,
        detected=True,
        phrases=[
            r"shak\w*\s+" + _OBJ + r"head",
            r"head\s+shak\w*",
            r"shakes?\s+no",
            r"disagrees?",
            r"shak(?:es|ing)\b",
        ],
        prototype="a person shakes their head",
        verbs=("shakes the head", "shake the head"),
        channels=(HEAD,),
    ),
    Event(
        TURN,
        detected=True,
        phrases=[
            r"turn\w*\s+" + _OBJ + r"(?:head|face)",
            r"cran\w*\s+" + _OBJ + r"neck",
            r"rubberneck\w*",
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
        prototype="a person turns their head to the side",
        verbs=("turns the head", "turn the head"),
        channels=(HEAD,),
        sided=True,
        holdable=True,
        max_hold_s=0.8,
    ),
    Event(
        "happy",
        emotion=True,
        phrases=[
            r"happ(?:y|ily|iness)",
            r"joy\w*",
            r"cheerful\w*",
            r"glad",
            r"delight\w*",
            r"pleased",
            r"laugh\w*",
            r"chuckl\w*",
            r"giggl\w*",
        ],
        prototype="a person looks happy",
        verbs=("looks happy", "look happy"),
        action_units={"mouthSmile_L": 1, "mouthSmile_R": 1, "cheekSquint_L": 0.5, "cheekSquint_R": 0.5},
        holdable=True,
    ),
    Event(
        "sad",
        emotion=True,
        phrases=[
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
        prototype="a person looks sad",
        verbs=("looks sad", "look sad"),
        action_units={
            "browInnerUp_L": 1,
            "browInnerUp_R": 1,
            "mouthFrown_L": 1,
            "mouthFrown_R": 1,
            "mouthSmile_L": -1,
            "mouthSmile_R": -1,
            "jawOpen": -0.5,
        },
        holdable=True,
    ),
    Event(
        "angry",
        emotion=True,
        phrases=[
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
        prototype="a person looks angry",
        verbs=("looks angry", "look angry"),
        action_units={
            "browDown_L": 1,
            "browDown_R": 1,
            "noseSneer_L": 0.7,
            "noseSneer_R": 0.7,
            "mouthPress_L": 0.3,
            "mouthPress_R": 0.3,
            "mouthSmile_L": -1,
            "mouthSmile_R": -1,
            "browInnerUp_L": -0.5,
            "browInnerUp_R": -0.5,
        },
        holdable=True,
    ),
    Event(
        "disgusted",
        emotion=True,
        phrases=[r"disgust\w*", r"grossed\s+out", r"revolt\w*", r"repuls\w*", r"sick(?:ened)?"],
        prototype="a person looks disgusted",
        verbs=("looks disgusted", "look disgusted"),
        action_units={
            "noseSneer_L": 1,
            "noseSneer_R": 1,
            "mouthUpperUp_L": 0.7,
            "mouthUpperUp_R": 0.7,
            "browDown_L": 0.5,
            "browDown_R": 0.5,
            "mouthSmile_L": -0.5,
            "mouthSmile_R": -0.5,
        },
        holdable=True,
    ),
    Event(
        "fearful",
        emotion=True,
        phrases=[r"fear\w*", r"afraid", r"scar\w*", r"frighten\w*", r"terrif\w*", r"anxious\w*", r"nervous\w*"],
        prototype="a person looks afraid",
        verbs=("looks afraid", "look afraid"),
        action_units={
            "browInnerUp_L": 1,
            "browInnerUp_R": 1,
            "eyeWide_L": 1,
            "eyeWide_R": 1,
            "mouthStretch_L": 0.7,
            "mouthStretch_R": 0.7,
            "mouthSmile_L": -0.5,
            "mouthSmile_R": -0.5,
        },
        holdable=True,
    ),
    Event(
        "surprised",
        phrases=[],
        verbs=("looks surprised", "look surprised"),
    ),
    Event(
        "contempt",
        emotion=True,
        phrases=[r"contempt\w*", r"scorn\w*", r"disdain\w*", r"sneer\w*"],
        prototype="a person looks at someone with contempt",
        verbs=("looks scornful", "look scornful"),
        action_units={"mouthSmile_L": 1, "mouthDimple_L": 0.7, "mouthSmile_R": -1, "mouthDimple_R": -0.5},
        holdable=True,
    ),
    Event(
        CLOSE_EYES,
        phrases=[
            r"clos\w*\s+" + _OBJ + r"eyes",
            r"eyes\s+(?:are\s+|stay\s+|kept\s+)?(?:closed|shut)",
            r"shut\w*\s+" + _OBJ + r"eyes",
        ],
        prototype="a person closes their eyes",
        verbs=("closes the eyes", "close the eyes"),
        channels=both_sides("eyeBlink"),
        symmetric=True,
        holdable=True,
        strength={0.35: (0.4, 0.5), 0.6: (0.5, 0.6), 1.0: (0.9, 0.95), 1.4: (0.95, 1.0)},
    ),
    Event(
        "gaze",
        phrases=[
            r"eyes?\s+(?:\w+\s+)?(?:dart\w*|shift\w*|mov\w*|flick\w*|drift\w*|go(?:es)?|turn\w*|slid\w*|wander\w*)\s+"
            r"(?:to\s+(?:the\s+)?)?" + _DIR,
            r"gaz\w*\s+(?:\w+\s+)?(?:to\s+(?:the\s+)?)?" + _DIR,
            r"(?:shifts?|shifting|moves?|moving|drops?|dropping|lowers?|lowering|raises?|raising|averts?|averting|"
            r"darts?|darting|darted|flicks?|flicking|flicked|cuts?|cutting|slides?|sliding|slid|turns?|turning|"
            r"turned|casts?|casting)\s+" + _OBJ + r"(?:gaze|eyes)(?:\s+(?:to\s+(?:the\s+)?)?" + _DIR + r")?",
            r"(?:looks?|looking|glanc\w*|peers?|peering|peeks?|peeking|stares?|staring)\s+(?:straight\s+)?(?:up|down)"
            r"(?:wards?)?",
            r"looks?\s+(?:to\s+(?:the\s+)?)?(?:left|right)\s+with\s+" + _OBJ + r"eyes",
            r"looks?\s+(?:down\s+|up\s+)?at\s+(?:the\s+)?(?:floor|ground|sky|ceiling|(?:her|his|their)\s+(?:feet|hands|lap))",
            r"side[- ]?eye\w*",
        ],
        prototype="a person looks up with their eyes",
        verbs=("gazes", "gaze"),
    ),
    Event(
        "roll eyes",
        phrases=[r"roll\w*\s+" + _OBJ + r"eyes", r"eye[- ]?roll\w*"],
        prototype="a person rolls their eyes",
    ),
    Event(
        "puff cheeks",
        phrases=[
            r"puff\w*\s+(?:up\s+|out\s+)?" + _OBJ + r"(?:left\s+|right\s+)?cheeks?(?:\s+out)?",
            r"cheeks?\s+(?:are\s+)?puff\w*(?:\s+out)?",
            r"blow\w*\s+(?:out\s+|up\s+)?" + _OBJ + r"cheeks(?:\s+out)?",
            r"puff\w*\s+(?:up|out)",
        ],
        prototype="a person puffs out their cheeks",
        sided=True,
    ),
    Event(
        "pout",
        phrases=[r"pout\w*", r"sulk\w*", r"push\w*\s+(?:out\s+)?" + _OBJ + r"(?:lower\s+)?lip(?:\s+out)?"],
        prototype="a person pouts",
    ),
    Event(
        "pucker",
        phrases=[r"pucker\w*", r"purs\w*\s+" + _OBJ + r"lips", r"(?:blows?|blowing)\s+a\s+kiss", r"kiss\w*"],
    ),
    Event(
        "press lips",
        phrases=[
            r"press\w*\s+" + _OBJ + r"lips(?:\s+together)?",
            r"tighten\w*\s+" + _OBJ + r"(?:lips|mouth)",
            r"lips\s+(?:are\s+)?(?:pressed|tight\w*|thin\w*)(?:\s+together)?",
            r"compress\w*\s+" + _OBJ + r"lips",
            r"(?:thin|tight)\s+lips",
        ],
        prototype="a person presses their lips together",
        sided=True,
    ),
    Event(
        "roll lips",
        phrases=[
            r"(?:rolls?|rolling|sucks?|sucking|tucks?|tucking|pulls?|pulling)\s+(?:in\s+)?" + _OBJ + r"lips(?:\s+in)?",
            r"bit\w*\s+" + _OBJ + r"(?:lower\s+|upper\s+)?lip",
        ],
    ),
    Event(
        "shrug",
        phrases=[r"shrug\w*"],
    ),
    Event(
        "grimace",
        phrases=[r"grimac\w*", r"stretch\w*\s+" + _OBJ + r"lips", r"cring\w*", r"clench\w*\s+" + _OBJ + r"teeth"],
        prototype="a person grimaces",
    ),
    Event(
        "funnel",
        phrases=[r"funnel\w*", r"o[- ]shape\w*", r"whistl\w*", r"(?:mouths?|forms?|makes?)\s+an?\s+[\"']?oh?\b[\"']?"],
    ),
    Event(
        "bare teeth",
        phrases=[r"bar\w*\s+" + _OBJ + r"teeth", r"shows?\s+" + _OBJ + r"teeth", r"snarl\w*"],
        sided=True,
    ),
    Event(
        "wrinkle nose",
        phrases=[
            r"wrinkl\w*\s+" + _OBJ + r"nose",
            r"nose\s+wrinkl\w*",
            r"scrunch\w*\s+(?:up\s+)?" + _OBJ + r"(?:nose|face)(?:\s+up)?",
        ],
        prototype="a person wrinkles their nose",
        sided=True,
    ),
    Event(
        "widen eyes",
        phrases=[
            r"widen\w*\s+" + _OBJ + r"eyes",
            r"eyes\s+(?:go\s+|are\s+|grow\s+)?wide",
            r"wide[- ]eyed",
            r"opens?\s+" + _OBJ + r"eyes\s+wide",
        ],
        prototype="a person widens their eyes",
    ),
    Event(
        "jaw forward",
        phrases=[
            r"(?:juts?|jutting|thrusts?|pushes|pushing|sticks?)\s+(?:out\s+)?"
            + _OBJ
            + r"(?:jaw|chin)(?:\s+(?:forward|out))?"
        ],
    ),
    Event(
        "jaw side",
        phrases=[
            r"(?:moves?|shifts?|slides?|pushes)\s+" + _OBJ + r"jaw\s+(?:to\s+(?:the\s+)?)?(?:left|right|sideways)"
        ],
        sided=True,
    ),
    Event(
        "mouth side",
        phrases=[
            r"(?:moves?|shifts?|pulls?|twists?|purses?)\s+"
            + _OBJ
            + r"mouth\s+(?:to\s+(?:the\s+|one\s+)?)?(?:left|right|side)",
            r"twist\w*\s+" + _OBJ + r"mouth",
        ],
        sided=True,
    ),
    Event(
        "tongue",
        phrases=[r"(?:sticks?\s+(?:out\s+)?" + _OBJ + r")?tongue\w*(?:\s+out)?"],
        unplaced="tongue: the face model has no tongue (ICT-FaceKit's 53 expressions), not made",
    ),
    Event(
        NEUTRAL,
        phrases=[
            r"neutral(?:\s+face|\s+expression)?",
            r"calm\w*",
            r"expressionless",
            r"blank\s+(?:face|expression|stare)",
            r"straight\s+face",
            r"(?:stays?|keeps?|remains?|sits?)\s+still",
            r"relax\w*",
            r"poker\s+face",
        ],
        prototype="a person keeps a neutral face",
        verbs=("keeps a neutral face", "keep a neutral face"),
    ),
    Event(
        "head wagging",
        parsed=False,
        verbs=("wags the head", "wag the head"),
    ),
    Event(
        "laugh",
        parsed=False,
        verbs=("laughs", "laugh"),
    ),
    Event(
        "sing",
        parsed=False,
        verbs=("sings", "sing"),
    ),
    Event(
        "look around",
        parsed=False,
        verbs=("looks around", "look around"),
    ),
]

# events that cannot happen at the same moment: the second is moved to follow the first (with a note)
CONFLICTS = [
    {CLOSE_EYES, BLINK},
    {CLOSE_EYES, SQUINT},
    {CLOSE_EYES, SURPRISE},
    {YAWN, TALK},
    {NOD, SHAKE_HEAD},
    {SMILE, "sad"},
    {"happy", "sad"},
    {"happy", "angry"},
    {SMILE, "angry"},
]

VOCABULARY: dict[str, Event] = {e.name: e for e in _EVENTS}
"""Every event by name, in the parser's order (its first events are the detectors')."""
DETECTED: tuple[str, ...] = tuple(e.name for e in _EVENTS if e.detected)
"""The events the dataset's detectors label, in their order."""
EMOTIONS: tuple[str, ...] = tuple(e.name for e in _EVENTS if e.emotion or e.name in ("surprised", NEUTRAL))
"""The emotions a prompt may name (the annotations' emotion words)."""


def channels(name: str) -> tuple[str, ...]:
    """The channels event ``name`` moves (an emotion: its action units that pull)."""
    e = VOCABULARY.get(name)
    if e is None:
        return ()
    if e.channels:
        return e.channels
    return tuple(k for k, w in (e.action_units or {}).items() if w > 0)
