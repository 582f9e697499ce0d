"""Every subcommand's --help runs, and its options' defaults are the config dataclasses' defaults."""

import argparse
import contextlib
import dataclasses
import io

import pytest

from anima.cli.main import build_parser, main


def _leaves(parser: argparse.ArgumentParser, path=()):
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        yield path
        return
    for name, p in subs[0].choices.items():
        yield from _leaves(p, path + (name,))


COMMANDS = list(_leaves(build_parser()))


def test_there_are_all_the_commands():
    assert len(COMMANDS) >= 23
    assert ("capture",) in COMMANDS and ("eval", "gesture") in COMMANDS and ("train", "pose") in COMMANDS


@pytest.mark.parametrize("cmd", COMMANDS, ids=[" ".join(c) for c in COMMANDS])
def test_help(cmd):
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit) as e:
        main([*cmd, "--help"])
    assert e.value.code == 0
    assert out.getvalue().startswith("usage: anima " + " ".join(cmd))


def test_group_alone_prints_its_help(capsys):
    assert main(["eval"]) == 2
    assert "landmarks" in capsys.readouterr().out


def test_defaults_come_from_the_configs():
    from anima.capture.config import CaptureConfig
    from anima.reenact.config import ReenactConfig

    p = build_parser()
    a = p.parse_args(["capture", "v.mp4", "--out", "o"])
    assert a.smooth_sigma == CaptureConfig().smooth_sigma and a.max_gap == CaptureConfig().max_gap
    a = p.parse_args(["reenact", "--target", "t.mp4"])
    r = ReenactConfig()
    assert (a.n, a.a, a.smooth, a.map_expressions) == (r.n, r.a, r.smooth, r.map_expressions)
    fields = {f.name for f in dataclasses.fields(ReenactConfig)}
    assert {"n", "a", "smooth", "map_expressions"} <= fields


@pytest.mark.parametrize(
    "argv",
    [
        ["capture", "v.mp4", "--out", "o", "--sigma", "nan"],
        ["capture", "v.mp4", "--out", "o", "--max-frames", "0"],
        ["reenact", "--target", "t.mp4", "--a", "1.5"],
        ["audio", "features", "x.wav", "--fps", "-1"],
        ["text2face", "hi", "--out", "o", "--seconds", "inf"],
    ],
)
def test_out_of_range_options_are_one_line_and_exit_2(argv, capsys):
    with pytest.raises(SystemExit) as e:
        main(argv)
    err = capsys.readouterr().err
    assert e.value.code == 2 and err.count("\n") == 1 and err.startswith("anima: error:")


def test_the_command_table_names_each_commands_module():
    """``COMMANDS`` maps every registered command to the module that registers it, and a parser built for
    one command holds that command."""
    import importlib

    from anima.cli.main import COMMANDS

    registered = {}
    for name in dict.fromkeys(COMMANDS.values()):
        sub = argparse.ArgumentParser().add_subparsers()
        importlib.import_module(f"anima.cli.{name}").register(sub)
        registered |= {c: name for c in sub.choices}
    assert registered == COMMANDS
    for command in COMMANDS:
        sub = next(a for a in build_parser(command)._actions if isinstance(a, argparse._SubParsersAction))
        assert command in sub.choices


def test_a_command_loads_only_its_own_group():
    """A cold ``anima gesture`` imports the gesture command's module, not capture, dataset build or eval
    (measured: start-up 0.35-0.45 s shorter on 2 cores)."""
    import subprocess
    import sys

    code = (
        "import sys; from anima.cli.main import build_parser; build_parser('gesture'); "
        "print(sorted(m for m in sys.modules if m.startswith('anima.cli.')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert "anima.cli.generate" in out
    for other in ("anima.cli.capture", "anima.cli.dataset", "anima.cli.evaluate", "anima.cli.train"):
        assert other not in out


@pytest.mark.parametrize("preset", [None, "2"])
def test_gesture_runs_with_one_blas_thread_unless_the_user_set_one(preset):
    """``anima gesture`` sets one BLAS thread before numpy loads (its products are small; a pool only spins
    against the preview's threads); a value the user set is kept. A fresh interpreter: numpy must not be
    loaded yet."""
    import json
    import os
    import subprocess
    import sys

    code = (
        "import contextlib, io, json, os\n"
        "from anima.cli.main import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    try:\n        main(['gesture', '--help'])\n    except SystemExit:\n        pass\n"
        "from threadpoolctl import threadpool_info\n"
        "print(json.dumps([os.environ.get('OPENBLAS_NUM_THREADS'), "
        "[p['num_threads'] for p in threadpool_info() if p['user_api'] == 'blas']]))\n"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
    if preset:
        env["OPENBLAS_NUM_THREADS"] = preset
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    var, threads = json.loads(r.stdout.strip().splitlines()[-1])
    assert var == (preset or "1")
    if not preset:
        assert threads and set(threads) == {1}


def test_eval_commands_and_eval_all_come_from_one_registry():
    """`anima eval --help` lists every evaluation of the registry (and `all`); `anima eval all` runs exactly
    the registry's rows, and each row's recorded command parses back into the same config (a file shipped
    inside anima is recorded by its path from the project's root, where the commands are run)."""
    import argparse
    import shlex
    from pathlib import Path

    from anima.cli.main import build_parser
    from anima.cli.options import config_from_args
    from anima.eval.registry import BY_NAME, EVALUATIONS, Context, rows

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    ev = next(a for a in sub.choices["eval"]._actions if isinstance(a, argparse._SubParsersAction))
    assert set(ev.choices) == {e.name for e in EVALUATIONS} | {"all"}
    for quick in (False, True):
        table = rows(Context("ds", Path("out"), Path("work"), quick))
        assert {e.name for e, _, _ in table} == set(BY_NAME)
        for e, name, cfg in table:
            argv = shlex.split(e.command(cfg))[1:]
            a = parser.parse_args(argv)
            back = config_from_args(e.config, a, [f for f in vars(cfg)])
            root = Path(__file__).resolve().parents[2]
            for f, v in vars(back).items():
                if isinstance(v, str) and v.startswith("anima/"):
                    setattr(back, f, str(root / v))
            assert back == cfg, (name, argv)
