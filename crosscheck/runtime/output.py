"""Output files written so a reader never sees a half-written or mixed set.

Every file of one command goes first to a temporary name beside its final one (same directory,
so the rename is atomic on POSIX file systems); `commit` then renames them all into place with
SIGINT held back, so Ctrl-C cannot land between two renames. An interrupted or failed command
removes its temporary files and leaves the directory as it was: the previous run's files,
complete and consistent with each other, or nothing. A command killed outright (SIGKILL) cannot
remove its temporary files; the next command writing into the directory removes them (their
name carries the pid of a process that no longer runs).

A directory holds only what the suite wrote and what its user put there: a command that
replaces a set of files (run, report) enters each file it commits, with a digest of its
content, in the directory's ledger (LEDGER), and removes a stale file (an old report beside new
results) only where the ledger says the suite wrote it and its content is still what the suite
wrote. A user's own report.md is never removed.
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import threading
from pathlib import Path

from crosscheck.runtime import interrupts

TMP_PREFIX = ".crosscheck-tmp-"
LEDGER = ".crosscheck-written.json"  # {file name: sha256 of what the suite wrote}


class Outputs:
    """The files of one command in one directory: stage them, then commit or discard."""

    def __init__(self, out_dir: str | Path):
        self.dir = Path(out_dir)
        self._staged: dict[str, Path] = {}  # final name -> temporary path

    def stage(self, name: str, text: str) -> Path:
        """Write `text` under a temporary name; returns that path (readable before commit)."""
        return self.stage_bytes(name, text.encode("utf-8"))

    def stage_bytes(self, name: str, data: bytes) -> Path:
        """Write `data` under a temporary name; returns that path (readable before commit)."""
        if not self._staged:
            self.dir.mkdir(parents=True, exist_ok=True)
            remove_orphans(self.dir)
        tmp = self.dir / f"{TMP_PREFIX}{os.getpid()}-{name}"
        self._staged[name] = tmp
        try:
            with open(tmp, "wb") as fh:
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())  # the data is on disk before the name points at it
        except OSError as exc:  # a full disk: the message names the file, not its temporary
            raise OSError(exc.errno, exc.strerror, str(self.dir / name)) from None
        return tmp

    def path(self, name: str) -> Path:
        return self.dir / name

    def commit(
        self, stale: tuple[str, ...] = (), *, after_interrupt: bool = False
    ) -> dict[str, Path]:
        """Rename every staged file into place and remove `stale` files this command did not
        write (an old report beside new results would look current); returns final paths.
        After a Ctrl-C only files that say so (`after_interrupt`: a campaign's stop status, its
        finished chunks) are committed."""
        if not after_interrupt:
            interrupts.check()  # an interrupt an engine swallowed: this command's files never land
        gone: list[str] = []
        ledger_tmp = None
        if stale:  # only a command that replaces a set of files keeps the ledger
            ledger = _read_ledger(self.dir)
            for name, tmp in self._staged.items():
                ledger[name] = _digest(tmp)
            gone = [n for n in stale if n not in self._staged and _ours(self.dir, n, ledger)]
            for name in gone:
                ledger.pop(name, None)
            ledger_tmp = self.dir / f"{TMP_PREFIX}{os.getpid()}-{LEDGER}"
            ledger_tmp.write_text(json.dumps(ledger, indent=1, sort_keys=True))
        with _sigint_held():
            for name in gone:
                (self.dir / name).unlink(missing_ok=True)
            for name, tmp in self._staged.items():
                os.replace(tmp, self.dir / name)
            if ledger_tmp is not None:
                os.replace(ledger_tmp, self.dir / LEDGER)
        done = {name: self.dir / name for name in self._staged}
        self._staged.clear()
        return done

    def discard(self) -> None:
        for tmp in self._staged.values():
            tmp.unlink(missing_ok=True)
        self._staged.clear()

    def __enter__(self) -> Outputs:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.discard()  # after a commit there is nothing left to discard


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _read_ledger(directory: Path) -> dict[str, str]:
    """The directory's ledger; an unreadable one counts as empty (nothing is then removed)."""
    try:
        data = json.loads((directory / LEDGER).read_text())
    except (OSError, ValueError):
        return {}
    return {str(k): str(v) for k, v in data.items()} if isinstance(data, dict) else {}


def _ours(directory: Path, name: str, ledger: dict[str, str]) -> bool:
    """Whether `name` in `directory` is a file the suite wrote and nobody changed since."""
    path = directory / name
    try:
        return path.is_file() and ledger.get(name) == _digest(path)
    except OSError:
        return False


def remove_orphans(directory: Path) -> list[Path]:
    """Remove the temporary files of commands that no longer run (killed while writing: their
    name holds their pid); returns what was removed. Another live command's files stay."""
    removed = []
    for tmp in directory.glob(f"{TMP_PREFIX}*"):
        pid = tmp.name[len(TMP_PREFIX) :].split("-", 1)[0]
        if pid.isdigit() and int(pid) != os.getpid() and not _running(int(pid)):
            tmp.unlink(missing_ok=True)
            removed.append(tmp)
    return removed


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process: running
        return True
    return True


class _sigint_held:
    """Block SIGINT and SIGTERM (main thread only) while the renames run; a signal sent
    meanwhile is delivered right after, when every file is already in place."""

    def __enter__(self):
        self._on = threading.current_thread() is threading.main_thread()
        if self._on:
            self._old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})

    def __exit__(self, *exc):
        if self._on:
            signal.pthread_sigmask(signal.SIG_SETMASK, self._old)


def write_atomic(path: str | Path, text: str, *, after_interrupt: bool = False) -> Path:
    """One file, atomically: the old content or the new, never a part."""
    path = Path(path)
    with Outputs(path.parent) as o:
        o.stage(path.name, text)
        return o.commit(after_interrupt=after_interrupt)[path.name]
