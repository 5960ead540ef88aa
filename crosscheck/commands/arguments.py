"""Command-line arguments shared by the commands, validated by one set of rules.

Every command that takes models, engines, a state count, a horizon or an output directory
declares them here, so `run`, `bench` and `sweep` refuse the same bad input with the same
one-line message (exit 2) before doing any work. Argument values are checked at parse time
(argparse `type=`); what needs the registries (model and engine names) is checked by
`resolve_models` / `resolve_engines` before the first computation.
"""

from __future__ import annotations

import argparse
import errno
import math
import os
import tempfile
from pathlib import Path

# The longest trajectory horizon `run` accepts. The trajectory stage integrates the reference
# at rtol 1e-12 and every engine at its finest step over the horizon; at 1000 s that is already
# the 1000 s stress scene's cost (minutes). Longer runs are a stress scene, not a check.
MAX_T_END = 1000.0


# Upper bounds of the counts: past them a command would run for days, exhaust memory or
# overflow a C integer (--workers 1e20) long before it said anything useful.
# states per model: each is one comparison per engine; many states are `crosscheck sweep`'s
MAX_STATES = 10_000
# worker processes: each holds every engine's models; more than this is no machine's core count
MAX_PROCESSES = 1024
# a sweep's sample index: indices are written to sweep.json, and JSON readers keep whole
# numbers exactly only below 2**53 (9.007e15)
MAX_INDEX = 10**15
# a sweep's samples: the parent keeps every error value of a campaign for exact quantiles
# (~1.6 GB at this many samples of one model; crosscheck.sweep.config)
MAX_SAMPLES = 10**7


def at_most(kind, upper: int, why: str):
    """`kind` (positive_int, nonnegative_int) refusing values above `upper`, saying `why`."""

    def parse(text: str) -> int:
        value = kind(text)
        if value > upper:
            raise argparse.ArgumentTypeError(f"{value} is more than {upper:,}: {why}")
        return value

    parse.__name__ = kind.__name__
    return parse


def states_count(text: str) -> int:
    """--states: consistent states per model, 1 to MAX_STATES."""
    return at_most(positive_int, MAX_STATES, "a campaign of many states is `crosscheck sweep`'s")(
        text
    )


def processes(text: str) -> int:
    """--jobs, --workers: worker processes, 1 to MAX_PROCESSES."""
    return at_most(positive_int, MAX_PROCESSES, "the worker processes this command starts")(text)


def positive_int(text: str) -> int:
    """An integer >= 1 (a count of states, samples, workers)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} must be at least 1")
    return value


def nonnegative_int(text: str) -> int:
    """An integer >= 0 (a seed, a first sample index, a number of cases kept)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"{value} must be at least 0")
    return value


def positive_seconds(text: str) -> float:
    """A finite duration > 0 (a time budget)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"{text} s: give a finite number of seconds > 0")
    return value


def finite_float(text: str) -> float:
    """Any finite number (a time t of `eval`)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text} is not finite")
    return value


def horizon(text: str) -> float:
    """A trajectory length in seconds: finite, > 0 and at most MAX_T_END."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(
            f"{text} s is not a finite horizon; give a length in seconds, at most {MAX_T_END:g}"
        )
    if value <= 0:
        raise argparse.ArgumentTypeError(
            f"{value:g} s: the horizon must be > 0 (use --instantaneous for no trajectory)"
        )
    if value > MAX_T_END:
        raise argparse.ArgumentTypeError(
            f"{value:g} s is longer than the {MAX_T_END:g} s the trajectory stage is sized for; "
            "long-horizon drift is what `crosscheck bench` (stress scenes) measures"
        )
    return value


def name_list(text: str) -> list[str]:
    """Comma-separated names, each given once: 'pinocchio,mujoco' -> ['pinocchio', 'mujoco']."""
    names = [n.strip() for n in text.split(",")]
    if not any(names):
        raise argparse.ArgumentTypeError(f"{text!r} names nothing; give comma-separated names")
    if "" in names:
        raise argparse.ArgumentTypeError(f"{text!r} has an empty name between commas")
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise argparse.ArgumentTypeError(f"{', '.join(repeated)} given more than once")
    return names


def _refuse(message: str) -> Exception:
    """A ModelInputError (one line, exit 2), imported on use: this module loads with the CLI
    before the models, so that a Ctrl-C during their import is answered with one line."""
    from reference.errors import ModelInputError

    return ModelInputError(message)


def unique(names: list[str], what: str) -> list[str]:
    """The names in order, refusing repeats (a repeated model would duplicate its records)."""
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise _refuse(f"{what} {', '.join(repeated)} given more than once")
    return list(names)


def resolve_models(names: list[str], files: list[str] | None = None) -> list[str]:
    """The models to run: when none is named, the --model-file models (``files``) if any were
    loaded, else all built-in ones; unknown names and repeats are refused before any work (the
    registry's error lists the valid names)."""
    from reference import models

    if not names:
        return list(files) if files else list(models.names())
    for name in unique(names, "model"):
        models.get(name)
    return list(names)


def resolve_engines(names: list[str] | None) -> list[str]:
    """The engines to compare: every registered engine that imports here when none is named;
    a named one must be registered (the error lists the registered ones) and import here."""
    from crosscheck.engines.registry import available_engines, get_engine

    if not names:
        return list(available_engines())
    for name in unique(names, "engine"):
        get_engine(name)
    return list(names)


def add_models(parser: argparse.ArgumentParser) -> None:
    """Positional model names (checked by resolve_models before any work) and --model-file."""
    parser.add_argument(
        "models", nargs="*", help="models (default: all, or the --model-file models when given)"
    )
    add_model_files(parser)


def control(text: str) -> tuple[str, float]:
    """An actuator control NAME=VALUE (--ctrl): a name and a finite number."""
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError(f"{text!r}: expected NAME=VALUE (an actuator's control)")
    try:
        number = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: {value!r} is not a number") from None
    if not math.isfinite(number):
        raise argparse.ArgumentTypeError(f"{text!r}: the control must be finite")
    return name.strip(), number


def add_model_files(parser: argparse.ArgumentParser, project: bool = True) -> None:
    """--model-file PATH (repeatable): an MJCF (.xml) or Python (.py) file of user models;
    with it, how an MJCF file is loaded: --project (an initial state off the constraint
    manifold is projected onto it; ``project=False`` where the command has its own --project,
    which then says the same of the files) and --ctrl NAME=VALUE (an actuator's control)."""
    parser.add_argument(
        "--model-file",
        action="append",
        default=[],
        metavar="PATH",
        help="load models from an MJCF (.xml) or Python (.py, a models() "
        "function) file; repeatable (docs/user_models.md)",
    )
    if project:
        _add_project(parser)
    parser.add_argument(
        "--ctrl",
        action="append",
        default=[],
        type=control,
        metavar="NAME=VALUE",
        help="the control of an MJCF file's actuator NAME (repeatable; default: keyframe 0's "
        "ctrl, else 0): its force at that control (gain and bias) is a load on its joint",
    )


def _add_project(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--project",
        action="store_true",
        help="project an MJCF file's initial state (keyframe 0 or qpos0) onto its constraint "
        "manifold, positions and velocities, where it is off it (else the file is refused); "
        "the records say by how much",
    )


def loading_options(args: argparse.Namespace) -> dict:
    """How the --model-file files are loaded: {"project": bool, "ctrl": {name: value}}; an
    actuator named twice is refused."""
    pairs = list(getattr(args, "ctrl", None) or [])
    unique([name for name, _ in pairs], "--ctrl for actuator")
    return {"project": bool(getattr(args, "project", False)), "ctrl": dict(pairs)}


def load_model_files(args: argparse.Namespace) -> list[str]:
    """Register the models of every --model-file and of the entry-point group
    `crosscheck.models` (a name clash or a bad file is one line, exit 2), before any model
    name is resolved; returns the files' model names in order. A command given files and no
    model names then runs just those (``args.user_models``, read by resolve_models)."""
    from importlib import metadata

    files = list(getattr(args, "model_file", None) or [])
    args.user_models = []
    options = loading_options(args)
    if options["ctrl"] and not files:
        raise _refuse("--ctrl sets the control of an actuator in a --model-file; give the file")
    if not files and not metadata.entry_points(group="crosscheck.models"):
        return []  # nothing to load: the commands stay as light as before (no MuJoCo import)
    from crosscheck.user_models import load_all, register_all
    from reference import models

    found = load_all(files, builtin_names=models.names(), **options)
    names = register_all(found)
    args.user_models = [um.name for um in found if um.kind != "entry-point"]
    return names


def add_engines(parser: argparse.ArgumentParser) -> None:
    """--engines a,b (checked by resolve_engines before any work)."""
    parser.add_argument(
        "--engines",
        type=name_list,
        default=None,
        metavar="E1,E2",
        help="engines, comma-separated (default: every registered engine that "
        "imports here, see `crosscheck engines`)",
    )


def output_dir(path: str, option: str = "--out") -> Path:
    """Check, before any work, that `path` is or can become a directory this process can write
    files into; leaves no trace (directories it had to create for the probe are removed again),
    so a command refused later has written nothing."""
    p = Path(path)
    shown = path if len(path) <= 80 else f"{path[:40]}...{path[-20:]}"  # the line stays short
    where = f"{option} {shown!r}"
    longest = max((len(os.fsencode(part)) for part in p.parts), default=0)
    if longest > 255:  # NAME_MAX of every common file system
        raise _refuse(
            f"{where}: a name in it is {longest} bytes long, more "
            "than the 255 a file system allows; give a shorter directory name"
        )
    try:
        a_file = p.exists() and not p.is_dir()
    except OSError:  # a whole path over PATH_MAX: the probe below says so
        a_file = False
    if a_file:
        raise _refuse(
            f"{where} is an existing file, not a directory; give a directory "
            "(the command writes its files inside it)"
        )
    created: list[Path] = []
    try:
        for d in reversed([p, *p.parents]):
            if not d.exists():
                d.mkdir()
                created.append(d)
        fd, probe = tempfile.mkstemp(dir=p, prefix=".crosscheck-probe-")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        why = exc.strerror or str(exc)
        if exc.errno == errno.ENAMETOOLONG:
            why += "; give a shorter path"
        raise _refuse(
            f"{where}: cannot write there ({why}); give a directory you can write to"
        ) from None
    finally:
        for d in reversed(created):
            try:
                d.rmdir()
            except OSError:
                pass
    return p


class OneLineParser(argparse.ArgumentParser):
    """argparse prints the whole usage block before an error; the CLI promises one line."""

    def error(self, message: str):  # type: ignore[override]
        # "crosscheck: error:" like every other bad input, whichever subcommand refused it
        self.exit(2, f"crosscheck: error: {message} (see `{self.prog} --help`)\n")


def float_list(text: str | None, what: str) -> list[float] | None:
    if text is None:
        return None
    out = []
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        try:
            out.append(float(item))
        except ValueError:
            raise _refuse(
                f"{what}: {item!r} is not a number (give comma-separated values)"
            ) from None
    return out


def assignments(pairs: list[str]) -> dict[str, float]:
    out = {}
    for pair in pairs or []:
        if "=" not in pair:
            raise _refuse(f"--set {pair!r}: expected NAME=VALUE")
        name, value = pair.split("=", 1)
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise _refuse(f"--set {pair!r}: {value!r} is not a number") from None
    return out


def add_state(parser: argparse.ArgumentParser, what: str) -> None:
    """--q, --u, --t and --project: the state a command starts from (`what` it is for)."""
    parser.add_argument(
        "--q", help=f"coordinates {what}, comma-separated (default: the model's initial state)"
    )
    parser.add_argument(
        "--u", help="speeds, comma-separated (q-dots for Lagrange/d'Alembert models)"
    )
    parser.add_argument("--t", type=finite_float, default=0.0, help="time (rheonomic constraints)")
    parser.add_argument(
        "--project",
        action="store_true",
        help="project the state onto the constraint manifold instead of refusing it (and a "
        "--model-file's initial state, as the other commands' --project)",
    )


def given_state(nm, args: argparse.Namespace) -> tuple[list, list]:
    """The state --q/--u/--t name (the model's initial state where they are left out), on the
    constraint manifold: projected with --project, else refused where it is off it."""
    model = nm.model
    q = float_list(args.q, "--q")
    u = float_list(args.u, "--u")
    q = list(model.initial_q) if q is None else q
    u = list(model.initial_u) if u is None else u
    if args.project:
        return nm.project(q, u, args.t)
    nm.check_consistent(q, u, args.t)
    return q, u
