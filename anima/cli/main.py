"""``anima``: the command line. Dispatch, error mapping and log silencing only; each command group lives in
its own module (``anima/cli/<group>.py``) with a ``register(subparsers)``, and each handler calls one library
function. Every command has ``--help``; errors print one line on stderr with exit code 2 (bad input),
3 (missing asset) or 4 (incompatible or unsafe file); ``--debug`` shows the traceback."""

from __future__ import annotations

import argparse
import atexit
import importlib
import os
import signal
import sys
import threading

os.environ.setdefault("GLOG_minloglevel", "2")
os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")

from anima import __version__
from anima.errors import AnimaError, extra_missing

COMMANDS = {
    "studio": "studio",
    "capture": "capture",
    "info": "capture",
    "export": "capture",
    "retarget": "avatar",
    "livelink": "capture",
    "vmc": "capture",
    "audio": "audio",
    "dataset": "dataset",
    "library": "library",
    "train": "train",
    "text2face": "generate",
    "gesture": "generate",
    "reenact": "reenact",
    "eval": "evaluate",
    "facemodel": "facemodel",
    "view": "view",
    "live": "live",
}
"""Each top-level command -> the module of ``anima/cli`` that registers it, in ``--help``'s order. Only the named
command's module (and its imports) is loaded: a cold ``anima gesture`` starts in half the time of importing all."""

ONE_BLAS_THREAD = {"gesture"}
"""Commands whose matrix products are all small (the gesture search's and the preview's): a pool of BLAS
threads would only spin against the command's own threads and its encoder. Measured on a cold ``anima
gesture --no-render`` (60 s of speech, 2 cores): 0.2 s less system CPU a run. Set before numpy loads; a
value the user set wins."""
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr (``anima: error: ...``) and exit code 2."""

    def error(self, message: str):
        where = self.prog.removeprefix("anima").strip()
        self.exit(2, f"anima: error: {where + ': ' if where else ''}{message} (see --help)\n")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser of every command, or of ``command`` alone (a key of :data:`COMMANDS`)."""
    p = Parser(prog="anima", description="Monocular video and speech to 3D avatar animation.")
    p.add_argument("--version", action="version", version=f"anima {__version__}")
    p.add_argument("--debug", action="store_true", help="show full tracebacks on errors")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    groups = [COMMANDS[command]] if command in COMMANDS else list(dict.fromkeys(COMMANDS.values()))
    for name in groups:
        importlib.import_module(f"anima.cli.{name}").register(sub)
    return p


def _command_of(argv: list[str]) -> str | None:
    """The command an argument list names: its first word that is not an option (the top-level options
    take no value)."""
    return next((x for x in argv if not x.startswith("-")), None)


def _silence_native_stderr() -> None:
    """MediaPipe/TFLite's C++ code writes start-up chatter straight to file descriptor 2. Point fd 2 at
    /dev/null and give Python's ``sys.stderr`` (anima's messages, progress bars) a copy of the real one."""
    try:
        sys.stderr.flush()
        real = os.dup(2)
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 2)
        os.close(devnull)
        sys.stderr = os.fdopen(real, "w", buffering=1, encoding=sys.stderr.encoding or "utf-8", errors="replace")
    except (OSError, ValueError, AttributeError):
        pass


def _one_line(e: BaseException) -> str:
    text = " ".join(str(e).split())
    return text if len(text) <= 400 else text[:397] + "..."


PIPE_CLOSED = 141  # 128 + SIGPIPE: what a shell reports for a command whose output pipe was closed


def _stdout_to_devnull() -> None:
    """Point stdout at /dev/null so that the interpreter's final flush does not fail on the closed pipe."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):
        pass


def _terminate(signum, frame):
    """SIGTERM ends a command like Ctrl-C: cleanup code runs (temporary files removed, Ray shut down)."""
    raise KeyboardInterrupt


def _interrupted(e: BaseException) -> bool:
    """Whether ``e`` was caused by a KeyboardInterrupt (Ctrl-C or SIGTERM): a C function that returns while the
    signal's exception is pending (numba's dispatcher) raises SystemError with the KeyboardInterrupt as cause."""
    seen = set()
    while e is not None and id(e) not in seen:
        if isinstance(e, KeyboardInterrupt):
            return True
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return False


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    command = _command_of(argv)
    if command in ONE_BLAS_THREAD and "numpy" not in sys.modules:
        for var in BLAS_THREAD_VARIABLES:
            os.environ.setdefault(var, "1")
    parser = build_parser(command)
    a = parser.parse_args(argv)
    a.argv = argv  # recorded in manifests (the command that made an artifact)
    if not a.debug and not os.environ.get("ANIMA_NATIVE_LOGS"):
        _silence_native_stderr()
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _terminate)
    if not getattr(a, "func", None):
        (getattr(a, "group_parser", None) or parser).print_help()
        return 0 if a.command is None else 2
    try:
        return int(a.func(a) or 0)
    except AnimaError as e:
        if a.debug:
            raise
        print(f"anima: error: {_one_line(e)}", file=sys.stderr)
        return e.exit_code
    except KeyboardInterrupt:
        print("anima: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader of stdout went away (`anima ... | head`): the work itself is done
        _stdout_to_devnull()
        return PIPE_CLOSED
    except MemoryError:
        print("anima: error: out of memory (the input is too large for this machine)", file=sys.stderr)
        return 2
    except Exception as e:
        if _interrupted(e):  # Ctrl-C inside a compiled kernel's call surfaces as a SystemError caused by it
            print("anima: interrupted", file=sys.stderr)
            return 130
        if a.debug:
            raise
        err = extra_missing(e, f"anima {a.command}")  # an optional library not installed: its extra, exit 3
        why = f"error: {_one_line(err)}" if err else f"internal error: {type(e).__name__}: {_one_line(e)}"
        print(f"anima: {why}{'' if err else ' (rerun with --debug for details)'}", file=sys.stderr)
        return err.exit_code if err else 1


def _stdout_done() -> None:
    """After the command's result: what a library's thread or exit handler prints (Ray's) goes to stderr."""
    try:
        sys.stdout.flush()
        sys.stderr.flush()
        os.dup2(sys.stderr.fileno(), sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # a closed or replaced stream: nothing more can be said
        pass


def run() -> None:
    """The ``anima`` console script: :func:`main`, then the exit. Every file a command writes is complete
    and closed when ``main`` returns, so once the exit handlers have run (Ray's shutdown, temporary folders)
    the process ends without the interpreter's teardown, which only frees memory and unloads numba's compiled
    code (0.15-0.2 s of a 3 s ``anima gesture``); with another non-daemon thread alive it exits the usual way."""
    try:
        rc = main()
    finally:  # also after argparse's own exits (--help, --version)
        _stdout_done()
    if any(not t.daemon and t is not threading.main_thread() for t in threading.enumerate()):
        sys.exit(rc)
    atexit._run_exitfuncs()
    _stdout_done()
    os._exit(rc)


if __name__ == "__main__":
    run()
