"""Ctrl-C that an engine swallowed is still an interrupt.

Python runs a SIGINT handler only when the interpreter regains control, and some engines'
C++ code does that from inside a solve (Exudyn checks for signals during time integration)
and then catches the KeyboardInterrupt itself: the solve reports "failed" and returns, or the
interrupt vanishes. Measured: `crosscheck run slider_crank --engines exudyn` interrupted at 3 s
exited 0 with every record written, at 4 s exited 1 with a failed trajectory record.
The command-line entry installs `on_sigint`, which remembers the signal; `check` raises
KeyboardInterrupt whenever one was seen, so a run never turns an interrupt into a record
(callers that convert engine errors into failed records ask first) and never writes its
outputs after one (Outputs.commit asks). SIGTERM (a CI job cancelled, `kill`) takes the same
path: the command stops its workers, leaves its outputs as they were and exits 143.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

_seen: list[int] = []


def on_sigint(signum, frame) -> None:
    _seen.append(signum)
    raise KeyboardInterrupt


def install() -> None:
    signal.signal(signal.SIGINT, on_sigint)
    signal.signal(signal.SIGTERM, on_sigint)


def seen() -> bool:
    return bool(_seen)


def terminated() -> bool:
    """Whether the signal that stopped the command was SIGTERM (exit 143), not Ctrl-C (130)."""
    return bool(_seen) and _seen[-1] == signal.SIGTERM


def check() -> None:
    """Raise KeyboardInterrupt if a SIGINT arrived, even if what it interrupted swallowed it."""
    if _seen:
        raise KeyboardInterrupt


@contextmanager
def deferred() -> Iterator[None]:
    """Hold Ctrl-C until the block has run, then deliver it: for a step that must not be cut
    half-way. Starting worker processes is one: a fork the interrupt cut off before we learnt
    the worker's pid would still be served by the server after we had gone, and that worker
    would print a traceback into the terminal."""
    if threading.current_thread() is not threading.main_thread():
        yield  # signal handlers belong to the main thread
        return
    held: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: held.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if held:
            _seen.append(held[0])
    if held and previous is not signal.SIG_IGN:
        raise KeyboardInterrupt
