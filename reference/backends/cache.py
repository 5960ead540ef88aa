"""The derivation cache's files: where they live, and reading them only when they are whole.

The cache is a cache: anything in it may be lost or damaged (a disk filled during a write, a
file truncated by a copy, garbage, an entry from another version under the right name), and
none of that may change an answer or stop a run. So

- a generated module is written with a last line `# sha256 <hex>` over its cache key and
  everything above it (`seal`); a file without that line, or whose digest differs, is
  damaged: stderr says so in one line and the module is derived again and replaced;
- a built C extension has a sidecar `<file>.sha256` written after its build; a file whose
  digest differs (a truncated .so would be a bus error when loaded) is never loaded, and is
  built again the same way;
- a cache location that cannot be used (not a directory, not writable) is replaced, with one
  line on stderr, by a private temporary directory removed at exit; worker processes inherit
  it through CROSSCHECK_CACHE_DIR;
- a write that fails (a full disk) leaves the entry out and the run goes on, said once.

The file names and keys are reference.backends.codegen's; this module is not among the
derivation's sources, so a change here does not miss the cache.
"""

from __future__ import annotations

import atexit
import hashlib
import importlib.util
import marshal
import os
import shutil
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

SEAL = "# sha256 "

# roots already probed in this process: configured root -> the directory used
_USABLE: dict[str, Path] = {}
_TOLD: set[str] = set()


def warn(message: str, once: str | None = None) -> None:
    """One line on stderr (`once`: a key, so that line is written once per process)."""
    if once is not None:
        if once in _TOLD:
            return
        _TOLD.add(once)
    print(f"crosscheck: warning: {message}", file=sys.stderr, flush=True)


def configured() -> str:
    """CROSSCHECK_CACHE_DIR, else $XDG_CACHE_HOME/multibody-crosscheck."""
    return os.environ.get("CROSSCHECK_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME", os.path.expanduser("~/.cache")), "multibody-crosscheck"
    )


def directory() -> Path:
    """The cache directory: the configured one where it can be written, else a private
    temporary one (said once on stderr)."""
    root = configured()
    hit = _USABLE.get(root)
    if hit is None:
        why = _unusable(Path(root))
        hit = Path(root) if why is None else _private(root, why)
        _USABLE[root] = hit
    return hit


def _unusable(path: Path) -> str | None:
    """Why `path` cannot hold the cache, or None: created if missing, then a file is written
    and removed (root ignores permission bits; the probe does not)."""
    try:
        if path.exists() and not path.is_dir():
            return "it is a file, not a directory"
        path.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=path, prefix=".probe-")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        return exc.strerror or str(exc)
    return None


def _private(root: str, why: str) -> Path:
    made = Path(tempfile.mkdtemp(prefix="crosscheck-cache-"))
    atexit.register(shutil.rmtree, made, True)
    os.environ["CROSSCHECK_CACHE_DIR"] = str(made)  # worker processes share it, unwarned
    _USABLE[str(made)] = made
    warn(
        f"the derivation cache {root} cannot be used ({why}); this run derives into a private "
        f"temporary cache, removed at exit: set CROSSCHECK_CACHE_DIR to a directory you can "
        f"write to keep the derivations"
    )
    return made


def seal(stem: str, body: str) -> str:
    """`body` with its last line: the digest of the cache key and the body."""
    return f"{body}{SEAL}{_digest(stem, body)}\n"


def _digest(stem: str, body: str) -> str:
    return hashlib.sha256(f"{stem}\0{body}".encode()).hexdigest()


def unseal(stem: str, text: str) -> str | None:
    """The body of a sealed entry of key `stem`, or None when it is not whole."""
    head, sep, tail = text.rstrip("\n").rpartition("\n" + SEAL)
    if not sep:
        return None
    body = head + "\n"
    return body if tail == _digest(stem, body) else None


def entry(path: Path, generate: Callable[[], str]) -> str:
    """The source of cache entry `path`: read when whole, else `generate()`d and written
    (a damaged entry is reported in one line, then replaced)."""
    stem = path.stem
    try:
        text = path.read_text()
    except FileNotFoundError:
        text = None
    except (OSError, UnicodeDecodeError) as exc:
        text = f"unreadable: {exc}"
    if text is not None:
        body = unseal(stem, text)
        if body is not None:
            return body
        what = "empty" if not text else "truncated, altered or from another version"
        warn(f"derivation cache entry {path} is damaged ({what}); deriving it again")
    body = generate()
    write(path, seal(stem, body))
    return body


def write(path: Path, text: str) -> bool:
    """Write `text` to `path` atomically (concurrent readers never see half a file); False
    when it cannot be written, said once: the entry is then derived again next time."""
    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp.write_text(text)
        os.replace(tmp, path)
        return True
    except OSError as exc:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:
            pass
        warn(
            f"cannot write to the derivation cache {path.parent} ({exc.strerror or exc}); "
            "derivations are not kept",
            once="write",
        )
        return False


def code_object(src: str, path: Path):
    """compile() of a cache entry's source, itself cached beside it as Python caches a
    module's bytecode: marshal's form, stamped with this interpreter's bytecode version, the
    source's sha256 and the payload's own, so a damaged file is compiled again."""
    stamp = importlib.util.MAGIC_NUMBER + hashlib.sha256(src.encode()).digest()
    code_path = path.with_suffix(f".{sys.implementation.cache_tag}.code")
    try:
        blob = code_path.read_bytes()
    except OSError:
        blob = b""
    head, payload = blob[: len(stamp) + 32], blob[len(stamp) + 32 :]
    if head == stamp + hashlib.sha256(payload).digest():
        try:
            return marshal.loads(payload)
        except (EOFError, ValueError, TypeError):
            pass  # compiled again and replaced below
    code = compile(src, str(path), "exec")
    payload = marshal.dumps(code)
    tmp = code_path.with_suffix(f".{os.getpid()}.tmp")
    try:
        tmp.write_bytes(stamp + hashlib.sha256(payload).digest() + payload)
        os.replace(tmp, code_path)
    except OSError:  # not kept: compiled again next time
        tmp.unlink(missing_ok=True)
    return code


def file_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def record_built(path: Path) -> None:
    """After a build: the digest of built file `path` beside it (`<file>.sha256`)."""
    write(path.with_name(path.name + ".sha256"), file_digest(path) + "\n")


def built_intact(path: Path) -> bool | None:
    """Whether built file `path` is the one its build recorded: None when absent, False (and
    one line on stderr) when damaged, True when its digest matches. A file built before
    digests were recorded is taken when its ELF layout is whole (its section headers, which
    the linker writes last, lie within it), and its digest is recorded then."""
    if not path.exists():
        return None
    sidecar = path.with_name(path.name + ".sha256")
    try:
        recorded = sidecar.read_text().strip() if sidecar.exists() else None
        if recorded is None and _elf_whole(path):
            record_built(path)
            return True
        ok = recorded == file_digest(path)
    except OSError:
        ok = False
    if not ok:
        warn(f"built module {path} is damaged (truncated or altered); building it again")
    return ok


def _elf_whole(path: Path) -> bool:
    """An ELF file no shorter than its own header says (e_shoff + e_shnum * e_shentsize)."""
    with open(path, "rb") as fh:
        head = fh.read(64)
        size = os.fstat(fh.fileno()).st_size
    if len(head) < 52 or head[:4] != b"\x7fELF" or head[4] not in (1, 2):
        return False
    order = "little" if head[5] == 1 else "big"
    wide = head[4] == 2
    shoff = int.from_bytes(head[0x28:0x30] if wide else head[0x20:0x24], order)
    at = 0x3A if wide else 0x2E
    entsize = int.from_bytes(head[at : at + 2], order)
    count = int.from_bytes(head[at + 2 : at + 4], order)
    return 0 < shoff and shoff + entsize * count <= size
