"""Python behaviour of long calls: Ctrl-C raises ``KeyboardInterrupt`` during a call (and
leaves the scene usable), and a run too large for the process's memory limit is a
``MemoryError``, never an abort. Each check runs in a subprocess, so a crash would show as its
exit status instead of killing the test run."""

from __future__ import annotations

import subprocess
import sys
import textwrap

from conftest import DATA, REPO

BRIDGESUS = REPO / "verification/paper/bridgesus/bridgesus.json"


def run_python(code: str, timeout: float = 120.0) -> str:
    """Run `code` in a fresh interpreter; it must exit 0. Its stdout."""
    # Unbuffered, and a hang dumps every thread's stack (to stderr, shown on failure). Python's
    # own Ctrl-C handler is installed: a process started in the background by a non-interactive
    # shell (a CI job) inherits SIGINT ignored, and Python then leaves it ignored.
    prelude = (
        "import faulthandler, signal\n"
        "faulthandler.dump_traceback_later(90, exit=True)\n"
        "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
    )
    code = prelude + textwrap.dedent(code)
    p = subprocess.run(
        [sys.executable, "-u", "-c", code],
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    assert p.returncode == 0, f"exit {p.returncode}\nstdout:\n{p.stdout}\nstderr:\n{p.stderr}"
    assert "PanicException" not in p.stderr, p.stderr
    return p.stdout


def test_ctrl_c_interrupts_long_calls_and_leaves_the_scene_usable():
    # Every call below would run for tens of seconds; a SIGINT 0.3 s into it must end it with
    # KeyboardInterrupt. The first one is the process's first call that returns arrays (the
    # case that used to raise PanicException).
    out = run_python(
        f"""
        import os, signal, threading, time
        import numpy as np
        import diffsoft

        s = diffsoft.Scene.load({str(BRIDGESUS)!r})
        calls = {{
            "simulate": lambda: s.simulate(20_000),
            "grad": lambda: s.grad(20_000, "final_com.y", ["density"]),
            "grad_implicit": lambda: s.grad(20_000, "final_com.y", ["density"], mode="implicit"),
            "simulate_batch": lambda: diffsoft.simulate_batch(s, 20_000, [{{}}, {{"density": 1000.0}}]),
            "grad_batch": lambda: diffsoft.grad_batch(s, 20_000, "final_com.y", ["density"], [{{}}, {{}}]),
        }}
        for name, call in calls.items():
            timer = threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT))
            timer.start()
            t0 = time.monotonic()
            try:
                call()
                print(name, "finished")
            except KeyboardInterrupt:
                print(name, "interrupted after", round(time.monotonic() - t0, 2), "s")
            timer.join()
        # The scene is unchanged and usable: the same short run as a fresh copy's.
        fresh = diffsoft.Scene.load({str(BRIDGESUS)!r})
        a, b = s.simulate(3), fresh.simulate(3)
        print("usable", bool(np.array_equal(a.positions, b.positions)))
        """
    )
    for name in ("simulate", "grad", "grad_implicit", "simulate_batch", "grad_batch"):
        assert f"{name} interrupted" in out, out
    assert "usable True" in out, out


def test_a_run_beyond_the_address_space_limit_is_a_memory_error():
    # Under `ulimit -v` the library sizes a run against the limit, not the host's free memory:
    # MemoryError (OutOfMemoryError), and the interpreter goes on.
    out = run_python(
        f"""
        import resource
        import diffsoft

        s = diffsoft.Scene.load({str(DATA / "beam.json")!r})
        resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))
        for name, call in {{
            "simulate": lambda: s.simulate(50_000_000),
            "grad": lambda: s.grad(50_000_000),
        }}.items():
            try:
                call()
                print(name, "ran")
            except MemoryError as e:
                assert isinstance(e, diffsoft.OutOfMemoryError), type(e)
                assert "address-space limit" in str(e), e
                print(name, "MemoryError")
        print("alive", s.simulate(2).positions.shape)
        """
    )
    assert "simulate MemoryError" in out and "grad MemoryError" in out, out
    assert "alive (3, 20, 3)" in out, out
