"""Ctrl-C and SIGTERM end a command as "interrupted" (exit 130), also when the signal arrives inside a numba
kernel's call, which turns it into a SystemError; and a live take's loop stops at the next frame instead."""

import subprocess
import sys

SCRIPT = r"""
import os, signal, threading, time
import numpy as np
from anima.capture.fit import _box_qp_gauss_seidel
from anima.cli.main import _interrupted
from anima.live.tracker import StopOnSignal

# a test run started as a background job inherits SIGINT ignored (the shell's rule for such jobs): take it back
signal.signal(signal.SIGINT, signal.default_int_handler)

F, n = 2000, 53
rng = np.random.default_rng(0)
A = rng.normal(size=(n, n))
N = np.repeat((A @ A.T + n * np.eye(n))[None], F, 0)
g = rng.normal(size=(F, n))
_box_qp_gauss_seidel(N, g, np.zeros((F, n)), 5, 1e-9)  # compiled (or loaded from the cache) before the timer

# 1. the default handler: the interrupt comes out of the kernel's call, as SystemError or KeyboardInterrupt
threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
try:
    t_end = time.time() + 30
    while time.time() < t_end:
        _box_qp_gauss_seidel(N, g, np.zeros((F, n)), 50, 1e-12)
    print("no interrupt")
except BaseException as e:
    print("raised", type(e).__name__, _interrupted(e))
print("plain error", _interrupted(ValueError("x")))

# 2. a take's handler: the kernel returns normally, the flag is set; a second signal raises at once
with StopOnSignal() as s:
    threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
    t_end = time.time() + 30
    while not s.requested and time.time() < t_end:
        _box_qp_gauss_seidel(N, g, np.zeros((F, n)), 50, 1e-12)
    print("flag", s.requested)
    try:
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(1)
        print("second signal ignored")
    except KeyboardInterrupt:
        print("second signal raised")
print("restored", signal.getsignal(signal.SIGINT) is signal.default_int_handler)
"""


def test_an_interrupt_inside_a_compiled_kernel_reads_as_interrupted_and_a_take_stops_at_a_flag():
    r = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=300)
    lines = r.stdout.splitlines()
    assert r.returncode == 0, r.stderr[-2000:]
    raised = [x for x in lines if x.startswith("raised")]
    assert raised and raised[0].split()[1] in ("SystemError", "KeyboardInterrupt") and raised[0].endswith("True")
    assert "plain error False" in lines
    assert "flag True" in lines and "second signal raised" in lines and "restored True" in lines
