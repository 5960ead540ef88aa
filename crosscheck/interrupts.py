"""Ctrl-C that an engine swallowed is still an interrupt.

Python runs a SIGINT handler only when the interpreter regains control, and some engines'
C++ code does that from inside a solve (Exudyn checks for signals during time integration)
and then catches the KeyboardInterrupt itself: the solve reports "failed" and returns, or the
interrupt vanishes. Measured: `crosscheck run slider_crank --engines exudyn` interrupted at 3 s
exited 0 with every record written, at 4 s exited 1 with a failed trajectory record.
The command-line entry installs `on_sigint`, which remembers the signal; `check` raises
KeyboardInterrupt whenever one was seen, so a run never turns an interrupt into a record
(callers that convert engine errors into failed records ask first) and never writes its
outputs after one (Outputs.commit asks).
"""

from __future__ import annotations

import signal

_seen: list[int] = []


def on_sigint(signum, frame) -> None:
    _seen.append(signum)
    raise KeyboardInterrupt


def install() -> None:
    signal.signal(signal.SIGINT, on_sigint)


def seen() -> bool:
    return bool(_seen)


def check() -> None:
    """Raise KeyboardInterrupt if a SIGINT arrived, even if what it interrupted swallowed it."""
    if _seen:
        raise KeyboardInterrupt
