"""The prompt suite of text -> face: does the motion do what the words say?

``anima eval text2face DATASET --prompts [FILE]`` generates every prompt of the suite
(``anima/eval/prompts/text2face.json``: 114 prompts written for the suite, not taken from the dataset's
descriptions; ``text2face_dev2.json``: 40 more, written after the timeline method was tuned on the first 114,
since then also developed on; ``text2face_heldout.json``: 40 more, the second held-out edition, run three times
and a development suite since; ``text2face_heldout3.json``: 40 frozen by their hash before any run, run once by
the final ``anima eval all``) with each method and seeds 0..``seeds``-1, and reads the motion back with
the dataset's own detectors (``anima.text2face.compose.detect_motion``: the detectors of ``anima dataset
build``, the clip's first and last frames held for 1 s on either side so brows and lids have a rest to be
measured against; the same rule for every method):

* **recall** of an attribute: the share of (prompt, seed) runs expecting it where it is detected; **false
  alarm**: the share of runs neither expecting it nor implying it where it is detected. The detectors'
  definitions overlap, and what one event implies is not a false alarm (``IMPLIED``: surprise is raised
  brows with an open mouth or wide eyes, talking and yawning open the mouth, a yawn narrows the eyes, raised
  brows while the mouth is open or talking read as surprise). Emotion and one-sided prompts are scored
  by their own checks, not in these two tables.
* **order accuracy** (prompts with two or more clauses): every clause's events found, and the first onset
  of each clause after the one before.
* **count accuracy** (prompts with a count): the detected number of that event equals the count.
* **side accuracy** (one-sided prompts): the named side's weight peaks above 0.3 and at least twice the
  other side's.
* **emotion checks** (``EMOTION_CHECKS``, each emotion's channel set): each named ARKit weight's mean
  over the clip rises above the same method's output for the neutral prompts, and its peak lies in the
  range of the captured clips (at most their largest value).
* **distinctness**: the largest difference of any expression weight or head rotation (rad) at any frame
  between the seed-0 motions of every pair of prompts whose expected events differ; how many pairs are the
  same motion (below ``SAME_MOTION``).

The methods: ``timeline`` (:mod:`anima.text2face.compose`, segments from the training videos' clips),
``seed model`` (the shipped cVQ-VAE + FaceFormer checkpoint, or ``--checkpoint``), ``retrieval`` (the motion
of the training clip with the nearest description in the sentence encoder's space). Numbers come with how
many prompts and runs stand behind them.
"""

from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from anima.core.contract import TEXT_FPS
from anima.core.events import BLINK, MOUTH_OPEN, RAISE_BROWS, SMILE, SQUINT, SURPRISE, TALK, YAWN
from anima.dataset.attributes import ATTRIBUTES
from anima.dataset.windows import read_clips
from anima.errors import InputError
from anima.eval.config import FROZEN_SUITES
from anima.eval.text2face.judge import ATTRIBUTES as READS
from anima.eval.text2face.judge import UNRELIABLE, JudgeConfig, judge_motion
from anima.io.assets import shown_path
from anima.io.validate import read_json
from anima.text2face.compose import EXPR_NAMES, Library, compose, detect_motion
from anima.text2face.encoders import encode_cached
from anima.text2face.prompt import parse

SUITE = Path(__file__).parents[1] / "prompts" / "text2face.json"
IMPLIED = {
    SURPRISE: {RAISE_BROWS, MOUTH_OPEN},
    TALK: {MOUTH_OPEN},
    YAWN: {MOUTH_OPEN, SQUINT},
}
EMOTION_CHECKS = {
    "happy": ["mouthSmile"],
    "surprised": ["browInnerUp", "eyeWide", "jawOpen"],
    "angry": ["browDown", "noseSneer"],
    "disgusted": ["browDown", "noseSneer"],
    "sad": ["browInnerUp", "mouthFrown"],
    "fearful": ["browInnerUp", "eyeWide"],
    "contempt": ["mouthSmile_L-R"],
}
SIDE_WEIGHT = {BLINK: "eyeBlink", RAISE_BROWS: "browInnerUp", SMILE: "mouthSmile"}  # one-sided checks
SAME_MOTION = 0.05  # no weight differs by more than 0.05, no rotation by more than 2.9 degrees


def load_suite(path: str | Path | None = None) -> list[dict]:
    """The prompts of a suite file, checked; a frozen suite (``FROZEN_SUITES``, by its file name) only when its
    bytes are the ones whose sha256 was written down when it was frozen."""
    p = Path(path) if path else SUITE
    frozen = FROZEN_SUITES.get(p.name)
    if frozen is not None and p.is_file() and hashlib.sha256(p.read_bytes()).hexdigest() != frozen:
        raise InputError(
            f"{p}: a frozen prompt suite whose content differs from the one frozen (sha256 {frozen[:12]}...): "
            "a held-out suite is never edited; write a new one"
        )
    doc = read_json(p, "prompt suite")
    rows = doc.get("prompts") if isinstance(doc, dict) else None
    if not isinstance(rows, list) or not rows:
        raise InputError(f"{p}: no 'prompts' list")
    kinds = {"single", "paraphrase", "sequence", "together", "count", "intensity", "emotion", "neutral", "side"}
    for i, r in enumerate(rows):
        where = f"{p}: prompt {i}"
        if not isinstance(r, dict) or not isinstance(r.get("prompt"), str) or not r["prompt"].strip():
            raise InputError(f"{where} has no text")
        sec = r.get("seconds")
        if isinstance(sec, bool) or not isinstance(sec, (int, float)) or not 0.5 <= sec <= 60:
            raise InputError(f"{where}: 'seconds' must be a number from 0.5 to 60")
        if r.get("kind") not in kinds:
            raise InputError(f"{where}: 'kind' must be one of {', '.join(sorted(kinds))}")
        if r.get("emotion") is not None and r["emotion"] not in EMOTION_CHECKS:
            raise InputError(f"{where}: unknown emotion {r['emotion']!r}")
        clauses = r.get("clauses", [])
        if not isinstance(clauses, list) or not all(isinstance(c, list) for c in clauses):
            raise InputError(f"{where}: 'clauses' must be a list of lists of events")
        for c in clauses:
            for e in c:
                if not isinstance(e, dict) or e.get("attribute") not in ATTRIBUTES:
                    raise InputError(f"{where}: unknown attribute {e.get('attribute') if isinstance(e, dict) else e!r}")
                n = e.get("count", 1)
                if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= 20:
                    raise InputError(f"{where}: 'count' must be a whole number from 1 to 20")
                if e.get("side") not in (None, "left", "right"):
                    raise InputError(f"{where}: 'side' must be left or right")
        if r["kind"] == "side" and not (
            clauses and clauses[0] and clauses[0][0].get("side") and clauses[0][0]["attribute"] in SIDE_WEIGHT
        ):
            raise InputError(
                f"{where}: a one-sided prompt needs a 'side' on its first event ({', '.join(SIDE_WEIGHT)})"
            )
    return rows


def expected(row: dict) -> set[str]:
    return {e["attribute"] for c in row.get("clauses", []) for e in c}


def allowed(row: dict) -> set[str]:
    exp = expected(row)
    out = set(exp)
    for a in exp:
        out |= IMPLIED.get(a, set())
    if RAISE_BROWS in exp and exp & {TALK, MOUTH_OPEN}:
        out.add(SURPRISE)
    if row.get("emotion") == "surprised":
        out |= {SURPRISE} | IMPLIED[SURPRISE]
    return out


def _channel(m: np.ndarray, stem: str) -> np.ndarray:
    if stem.endswith("_L-R"):
        b = stem[:-4]
        return m[:, EXPR_NAMES.index(b + "_L")] - m[:, EXPR_NAMES.index(b + "_R")]
    idx = [i for i, n in enumerate(EXPR_NAMES) if n == stem or n.startswith(stem + "_")]
    return m[:, idx].mean(1)


def _per_attribute(rows: list[dict], events: dict, attributes, scored: list[int]) -> dict:
    """Per attribute: its recall over the runs of the prompts that ask for it, its false alarms over those of
    the prompts that do not allow it (among the ``scored`` prompts)."""
    per_attr = {}
    for a in attributes:
        pos = [i for i in scored if a in expected(rows[i])]
        neg = [i for i in scored if a not in allowed(rows[i])]
        hit = [any(e[0] == a for e in ev) for i in pos for ev in events[i]]
        fa = [any(e[0] == a for e in ev) for i in neg for ev in events[i]]
        per_attr[a] = {
            "recall": round(float(np.mean(hit)), 3) if hit else None,
            "false_alarm": round(float(np.mean(fa)), 3) if fa else None,
            "prompts": len(pos),
            "runs": len(hit),
        }
    return per_attr


def _emotion_checks(rows: list[dict], runs: dict, captured_max: dict) -> list[dict]:
    """Per emotion prompt and checked weight: its rise over the same method's neutral prompts and its peak
    against the captured maximum (none without neutral prompts)."""
    neutral = [m for i, r in enumerate(rows) if r["kind"] == "neutral" for m in runs[i]]
    emo = []
    if neutral:
        stems = [stem for s in EMOTION_CHECKS.values() for stem in s]
        base = {stem: float(np.mean([_channel(m, stem).mean() for m in neutral])) for stem in stems}
        for i, r in enumerate(rows):
            e = r.get("emotion") or ("surprised" if r["kind"] == "emotion" and SURPRISE in expected(r) else None)
            if not e:
                continue
            for stem in EMOTION_CHECKS[e]:
                vals = [float(_channel(m, stem).mean()) for m in runs[i]]
                peak = max(float(_channel(m, stem).max()) for m in runs[i])
                rise = float(np.mean(vals)) - base[stem]
                emo.append(
                    {
                        "prompt": r["prompt"],
                        "emotion": e,
                        "weight": stem,
                        "rise": round(rise, 4),
                        "peak": round(peak, 3),
                        "captured_max": captured_max.get(stem),
                        "holds": bool(rise > 0.01 and peak <= captured_max.get(stem, 1.0) + 1e-6),
                    }
                )
    return emo


def _seed0_distances(rows: list[dict], runs: dict) -> list[float]:
    """Between the seed-0 motions of every two prompts that ask for different things: the largest difference
    of any expression weight or head rotation (rad) at any frame."""
    keys = {
        i: frozenset((e["attribute"], e["count"]) for c in rows[i].get("clauses", []) for e in c)
        | {rows[i].get("emotion")}
        for i in runs
    }
    dists = []
    ids = sorted(runs)
    for x in range(len(ids)):
        for y in range(x + 1, len(ids)):
            i, j = ids[x], ids[y]
            if keys[i] != keys[j]:
                a, b = runs[i][0], runs[j][0]
                T = min(len(a), len(b))
                # the largest difference of any expression weight or head rotation (rad) at any frame
                dists.append(float(np.abs(a[:T] - b[:T]).max()))
    return dists


def score_runs(
    rows: list[dict], runs: dict[int, list[np.ndarray]], captured_max: dict, detector=None, attributes=None
) -> dict:
    """``runs[i]``: the motions of prompt i (one per seed). ``detector``: motion -> events (default: the
    dataset's detectors, :func:`anima.text2face.compose.detect_motion`; the independent judge with
    ``--judge``), reading ``attributes`` (default: the detectors'); order and count are scored on the prompts
    whose events it reads."""
    attributes = tuple(attributes or ATTRIBUTES)
    scored = [i for i, r in enumerate(rows) if r["kind"] not in ("emotion", "side")]
    detector = detector or detect_motion
    events = {i: [detector(m) for m in runs[i]] for i in runs}
    per_attr = _per_attribute(rows, events, attributes, scored)
    order, count, side = [], [], []
    for i, r in enumerate(rows):
        cl = r.get("clauses", [])
        readable = expected(r) <= set(attributes)
        for ev, m in zip(events[i], runs[i]):
            if r["kind"] == "side":
                e = cl[0][0]
                stem = SIDE_WEIGHT[e["attribute"]]
                me, other = ("_L", "_R") if e["side"] == "left" else ("_R", "_L")
                a, b = m[:, EXPR_NAMES.index(stem + me)].max(), m[:, EXPR_NAMES.index(stem + other)].max()
                side.append(bool(a > 0.3 and a >= 2 * b))
                continue
            if not readable:
                continue
            if len(cl) >= 2:
                onsets = []
                for c in cl:
                    s = [s for n, s, _ in ev if n == c[0]["attribute"]]
                    onsets.append(s)
                ok = all(onsets)
                if ok:  # each clause's first onset after the previous clause's (allowing a shared event)
                    t = -1.0
                    for s in onsets:
                        later = [x for x in s if x > t]
                        if not later:
                            ok = False
                            break
                        t = min(later)
                order.append(bool(ok))
            for c in cl:
                for e in c:
                    if e["count"] > 1:
                        count.append(sum(1 for n, _, _ in ev if n == e["attribute"]) == e["count"])
    emo = _emotion_checks(rows, runs, captured_max)
    dists = _seed0_distances(rows, runs)
    dists = np.array(dists) if dists else np.zeros(1)

    def frac(v):
        return {"accuracy": round(float(np.mean(v)), 3) if v else None, "runs": len(v)}

    return {
        "per_attribute": per_attr,
        "order": frac(order),
        "count": frac(count),
        "side": frac(side),
        "emotion_checks": {
            "holds": int(sum(c["holds"] for c in emo)),
            "of": len(emo),
            "checks": emo,
        },
        "distinct": {
            "pairs": int(len(dists)),
            "same_motion_pairs": int((dists < SAME_MOTION).sum()),
            "min_distance": round(float(dists.min()), 4),
            "median_distance": round(float(np.median(dists)), 4),
        },
        "min_recall": min((v["recall"] for v in per_attr.values() if v["recall"] is not None), default=None),
        "max_false_alarm": max(
            (v["false_alarm"] for v in per_attr.values() if v["false_alarm"] is not None), default=None
        ),
    }


def captured_maxima(lib: Library) -> dict:
    X = np.concatenate(lib.motion)
    return {stem: round(float(np.max(_channel(X, stem))), 3) for s in EMOTION_CHECKS.values() for stem in s}


def evaluate_prompts(
    dataset,
    suite: str | Path | None = None,
    seeds: int = 3,
    checkpoint: str | None = None,
    progress: bool = True,
    judge: bool = False,
) -> dict:
    from anima.text2face.generate import Generator

    rows = load_suite(suite)
    t0 = time.perf_counter()
    lib = Library.from_dataset(dataset)
    load_s = time.perf_counter() - t0
    clips = [c for c in read_clips(dataset) if c.split == "train"]
    gen = Generator(checkpoint)
    enc = gen.encoder
    pool_texts = [(k, t) for k, c in enumerate(clips) for t in c.texts]
    pool_E = encode_cached(enc, [t for _, t in pool_texts])
    prompt_E = enc.encode([r["prompt"] for r in rows])
    n_frames = [int(round(r["seconds"] * TEXT_FPS)) for r in rows]

    def retrieval(i):
        k = pool_texts[int((pool_E @ prompt_E[i]).argmax())][0]
        m = clips[k].motion
        T = n_frames[i]
        return m[:T] if len(m) >= T else np.concatenate([m, np.repeat(m[-1:], T - len(m), 0)])

    methods = {}
    compose_s, notes, plans, refused = [], {}, {}, {}
    runs: dict[str, dict[int, list]] = {"timeline": {}, "seed model": {}, "retrieval": {}}
    for i, r in enumerate(tqdm(rows, desc="prompts", disable=not progress)):
        plan = parse(r["prompt"], enc)
        plans[i] = [(e.attribute, e.count, e.clause) for e in plan.events]
        if plan.notes:
            notes[r["prompt"]] = plan.notes
        runs["timeline"][i], runs["seed model"][i] = [], []
        for s in range(seeds):
            t = time.perf_counter()
            try:
                m, _ = compose(plan, lib, n_frames[i], s)
            except InputError as err:  # the events do not fit the length asked for: scored as a still face
                refused.setdefault(r["prompt"], str(err))
                m = np.repeat(lib.neutral[None], n_frames[i], 0)
            compose_s.append((n_frames[i], time.perf_counter() - t))
            runs["timeline"][i].append(m)
            lo, hi = gen.length_range
            runs["seed model"][i].append(gen.generate([r["prompt"]], int(np.clip(n_frames[i], lo, hi)), s)[0])
        runs["retrieval"][i] = [retrieval(i)] * seeds
    p99 = captured_maxima(lib)
    for name, rr in runs.items():
        methods[name] = score_runs(rows, rr, p99)
    t90 = [s for n, s in compose_s if n == 90]
    judged = judge_runs(rows, runs, p99, progress) if judge else None
    return {
        "protocol": {
            "suite": _suite_name(suite),
            "prompts": len(rows),
            "kinds": {k: sum(r["kind"] == k for r in rows) for k in dict.fromkeys(r["kind"] for r in rows)},
            "seeds": seeds,
            "detectors": "the dataset's (anima.dataset.attributes), first/last frame held 1 s either side",
            "library": f"{len(lib.motion)} (text, motion) clips of the training videos, "
            f"{sum(len(m) for m in lib.motion) / TEXT_FPS / 60:.1f} min; segments per event {lib.counts}",
            "seed_model": shown_path(gen.path),
            "retrieval": f"nearest of {len(pool_texts)} training descriptions (sentence encoder {enc.name})",
            "implied": {k: sorted(v) for k, v in IMPLIED.items()},
        },
        "methods": methods,
        "timing": {
            "library_load_s": round(load_s, 3),
            "compose_90_frames_median_s": round(float(np.median(t90)), 4) if t90 else None,
            "compose_90_frames_max_s": round(float(np.max(t90)), 4) if t90 else None,
        },
        "parsed": {rows[i]["prompt"]: plans[i] for i in plans},
        "notes": notes,
        "timeline_refused": refused,
    } | ({"judge": judged} if judged else {})


def _suite_name(suite: str | Path | None) -> str:
    """How a result names its suite: a shipped suite by its file name (not where anima is installed), a
    user's file as given."""
    if not suite:
        return SUITE.name
    p = Path(suite)
    return p.name if p.resolve().parent == SUITE.parent.resolve() else str(suite)


def judge_runs(rows: list[dict], runs: dict, captured_max: dict, progress: bool = True) -> dict:
    """Every method's seed-0 motions scored by the independent judge (:mod:`anima.eval.text2face.judge`) and by the
    dataset's detectors under the same definitions, and the prompts where the two disagree on whether the
    expected events were all found."""
    cfg = JudgeConfig()
    out = {"what": "seed 0 of every prompt; render -> MediaPipe Face Mesh -> landmark geometry "
                   "(anima/eval/text2face/judge.py)",
           "reads": list(READS), "unreliable": UNRELIABLE, "config": vars(cfg), "methods": {},
           "detectors_on_seed_0": {}, "disagree": {}}  # fmt: skip
    for name, rr in runs.items():
        first = {i: rr[i][:1] for i in rr}
        cache = {}
        with tqdm(total=len(first), desc=f"judge {name}", disable=not progress) as bar:
            for ms in first.values():
                cache[id(ms[0])] = judge_motion(ms[0], TEXT_FPS, cfg)
                bar.update()
        out["methods"][name] = score_runs(rows, first, captured_max, lambda m: cache[id(m)], READS)
        out["detectors_on_seed_0"][name] = score_runs(rows, first, captured_max, attributes=READS)
        diff = []
        for i, r in enumerate(rows):
            want = expected(r)
            if not want or r["kind"] in ("emotion", "side") or not want <= set(READS):
                continue
            by_judge = want <= {a for a, _, _ in cache[id(first[i][0])]}
            by_detectors = want <= {a for a, _, _ in detect_motion(first[i][0])}
            if by_judge != by_detectors:
                diff.append({"prompt": r["prompt"], "judge_finds_all": by_judge, "detectors_find_all": by_detectors})
        out["disagree"][name] = diff
        out.setdefault("events", {})[name] = {
            rows[i]["prompt"]: [[a, round(t0, 2), round(t1, 2)] for a, t0, t1 in cache[id(first[i][0])]] for i in first
        }
    return out


def _lowest(m: dict) -> str:
    """The lowest event recall and which event, e.g. "0.17 (surprise)" or "1.00 (every event)"."""
    per = {a: v["recall"] for a, v in m["per_attribute"].items() if v.get("recall") is not None}
    if not per:
        return "-"
    low = min(per.values())
    names = [a for a, v in per.items() if v == low]
    return f"{low:.2f} (" + ("every event" if len(names) == len(per) else ", ".join(names)) + ")"


def _highest_false_alarm(m: dict) -> str:
    per = {a: v["false_alarm"] for a, v in m["per_attribute"].items() if v.get("false_alarm") is not None}
    if not per:
        return "-"
    high = max(per.values())
    return f"{high:.2f}" + ("" if high == 0 else " (" + ", ".join(a for a, v in per.items() if v == high) + ")")


def _acc(x: dict) -> str:
    return "-" if not x.get("runs") else f"{x['accuracy']:.2f} ({x['runs']} runs)"


def judge_summary(r: dict) -> list[str]:
    """The headline of a prompt suite: the independent judge (rendered, tracked with MediaPipe, events from
    landmark geometry) per event, beside the detectors on the same seed-0 runs; [] without ``--judge``."""
    j = r.get("judge")
    if not j:
        return []
    p = r["protocol"]
    reads = json.loads(j["reads"]) if isinstance(j["reads"], str) else j["reads"]
    out = [
        f"{p['prompts']} prompts ({Path(p.get('suite', 'suite')).name}), seed 0. Independent judge (rendered, "
        "tracked with MediaPipe, events from landmark geometry), recall per event, judge / detectors on the same "
        "runs:",
        "",
        "| method | "
        + " | ".join(a + (" (unreliable)" if a in j.get("unreliable", {}) else "") for a in reads)
        + " | order | count | highest false alarm | disagree |",
        "|---|" + "---|" * (len(reads) + 4),
    ]
    det = j.get("detectors_on_seed_0", {})
    for name, m in j["methods"].items():
        dm = det.get(name, {}).get("per_attribute", {})

        def cell(a, m=m, dm=dm):
            jr = m["per_attribute"].get(a, {}).get("recall")
            dr = dm.get(a, {}).get("recall")
            return "-" if jr is None else f"{jr:.2f}" + ("" if dr is None else f" / {dr:.2f}")

        out.append(
            f"| {name} | "
            + " | ".join(cell(a) for a in reads)
            + f" | {_acc(m['order'])} | {_acc(m['count'])} | {_highest_false_alarm(m)} | "
            f"{len(j['disagree'].get(name, []))} prompts |"
        )
    return out


def detectors_summary(r: dict) -> list[str]:
    """Every method read back by the dataset's own detectors: for the timeline a consistency check, not evidence
    (the same detectors labelled the segments it composes from)."""
    p = r["protocol"]
    out = [
        f"{p['prompts']} prompts ({Path(p.get('suite', 'suite')).name}) x {p['seeds']} seeds; detectors: "
        f"{p['detectors']}. The timeline's recall and false alarms here are circular: the detectors that read "
        "them labelled the segments it composes.",
        "",
        "| method | lowest event recall | highest false alarm | order | count | side | emotion checks | "
        "same-motion pairs |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, m in r["methods"].items():
        d = m["distinct"]
        out.append(
            f"| {name} | {_lowest(m)} | {_highest_false_alarm(m)} | {_acc(m['order'])} | {_acc(m['count'])} | "
            f"{_acc(m['side'])} | {m['emotion_checks']['holds']} / {m['emotion_checks']['of']} | "
            f"{d['same_motion_pairs']} of {d['pairs']:,} |"
        )
    return out


def prompts_summary(r: dict) -> list[str]:
    """The markdown of ``eval all``: the independent judge first (with ``--judge``; the headline), then every
    method by the dataset's detectors (a consistency check for the timeline)."""
    judge = judge_summary(r)
    return judge + ([""] if judge else []) + detectors_summary(r)
