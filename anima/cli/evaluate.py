"""``anima eval ...``: generated from the registry (:mod:`anima.eval.registry`): one subcommand per evaluation,
its options from its config, and ``anima eval all`` running every row. Each prints its result (JSON with
``--json``; the learned evaluations print JSON either way)."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

from anima.cli.common import emit, group
from anima.cli.options import add_options, config_from_args
from anima.dataset.storage import check_dataset
from anima.dataset.windows import read_clips, read_windows
from anima.errors import InputError
from anima.eval.all import read_results, run_all
from anima.eval.config import AllEval
from anima.eval.registry import EVALUATIONS, Context, Evaluation, rows
from anima.io.outdir import check_out_dir


def _fields(cls) -> list[str]:
    return [f.name for f in dataclasses.fields(cls)]


def register(sub) -> None:
    esub = group(sub, "eval", "evaluations that print JSON", "eval_command", "EVAL")
    names = [name for _, name, _ in rows(Context("DB", Path("OUT"), Path("WORK"), False))]
    eall = esub.add_parser(
        "all",
        help="every evaluation in one run: one results file and a markdown summary",
        description=f"Runs {', '.join(names)} as their own commands do, and writes OUT/results.json (per row: "
        "command, status, minutes, result; the commit, the shared data's and the dataset's fingerprints, the "
        "machine) and OUT/summary.md. A row that cannot run (e.g. missing data) is recorded as skipped; "
        "exit 3 when one failed. The pose row trains the ablation's lifters in the work folder (no lifter "
        "ships). --jobs 2 runs the rows side by side in two processes (the two long rows, gesture and "
        "text2face, first); the measured runs and their minutes per row are in docs/architecture.md.",
    )
    add_options(eall, AllEval, _fields(AllEval))
    eall.add_argument("--json", action="store_true")
    eall.set_defaults(func=cmd_all)
    for ev in EVALUATIONS:
        p = esub.add_parser(ev.name, help=ev.help, description=ev.description)
        add_options(p, ev.config, _fields(ev.config))
        p.add_argument(
            "--json",
            action="store_true",
            help=None if ev.text else "no progress output (the result is JSON either way)",
        )
        p.set_defaults(func=lambda a, ev=ev: cmd_eval(ev, a))


def cmd_eval(ev: Evaluation, a) -> int:
    cfg = config_from_args(ev.config, a, _fields(ev.config))
    ev.check(cfg)  # before the evaluation's heavy imports
    module = ev.runner()
    result = module.run(cfg, progress=not a.json)
    return emit(result, a.json or not ev.text, getattr(module, "text", None))


def cmd_all(a) -> int:
    cfg = config_from_args(AllEval, a, _fields(AllEval))
    out = check_out_dir(cfg.out, inputs=[cfg.db])
    if cfg.resume:
        read_results(out)  # a results file that is not anima's is refused before an hour of work
    check_dataset(cfg.db)
    # the dataset read in full before an hour of work: a broken one is refused now, not when its row comes
    if not read_windows(cfg.db).n or not read_clips(cfg.db):
        raise InputError(f"{cfg.db}: the dataset needs (audio, motion) windows and (text, motion) clips")
    say = None if a.json else (lambda line: print(f"anima eval all: {line}", file=sys.stderr, flush=True))
    command = " ".join(["anima", *sys.argv[1:]])
    r = run_all(dataclasses.replace(cfg, out=str(out)), say, command)
    summary = {
        "results": str(Path(out) / "results.json"),
        "summary": str(Path(out) / "summary.md"),
        "minutes": round(r["wall_s"] / 60, 1),
        "rows": {n: e["status"] for n, e in r["rows"].items()},
    }
    emit(summary, a.json)
    if r["failed"]:
        print(
            f"anima: error: evaluation(s) failed: {', '.join(r['failed'])} (see {summary['results']})", file=sys.stderr
        )
        return 3
    return 0
