"""The order in which `crosscheck run --jobs N` hands its models to the workers: longest first.

A run ends when its last model does. Handed out in the models' order, a long model that comes
late (double_pendulum_3d, 5.9 s of a 34 s two-worker run with every engine) starts when the
other worker has little left, and that worker then waits for it. Handing out the longest
first (Graham's LPT rule) ends it within 7/6 of the best order's time on two workers, given
the times (benchmarks/run_time.md, "Where a warm run's time goes", has the figures).

A model's time is the one the last run with the same settings measured (engines, states,
trajectories and their horizon), kept beside the derivation cache. A model without a time
goes first: it may be long. The order changes when each model starts, never what a run
computes: the parent puts the results back in the models' order.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Mapping, Sequence

FILE = "run_times.json"


def setting_key(engines: Sequence[str], n_states: int, trajectories: bool, t_end: float) -> str:
    """What a model's time depends on, beyond the model: one entry of the times file each."""
    horizon = f"trajectories {t_end!r} s" if trajectories else "instantaneous"
    return f"{','.join(engines)} | {n_states} states | {horizon}"


def _path():
    from reference.backends.codegen import cache_dir

    return cache_dir() / FILE


def _read() -> dict:
    """The times file's content, or {} when there is none or it cannot be read: the times
    only order the work, so a damaged file costs at most one run's balance and is rewritten."""
    try:
        data = json.loads(_path().read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def known_times(key: str) -> dict[str, float]:
    """{model: seconds} the last runs with this setting measured (valid numbers only)."""
    entry = _read().get(key)
    if not isinstance(entry, dict):
        return {}
    return {
        name: float(t)
        for name, t in entry.items()
        if isinstance(t, int | float) and not isinstance(t, bool) and t >= 0.0
    }


def hand_out_order(names: Sequence[str], times: Mapping[str, float]) -> list[int]:
    """Indices into `names`: those without a time first (in their order), then the longest
    first (ties in the models' order)."""
    unknown = [i for i, n in enumerate(names) if n not in times]
    timed = sorted((i for i, n in enumerate(names) if n in times), key=lambda i: -times[names[i]])
    return unknown + timed


def remember_times(key: str, times: Mapping[str, float]) -> None:
    """Merge this run's times into the file (other settings' and other models' kept), atomically:
    two runs finishing together each leave a whole file. A cache directory that cannot be
    written (read-only, full) leaves the order as it was; the run's results do not depend on it."""
    data = _read()
    entry = data.get(key) if isinstance(data.get(key), dict) else {}
    data[key] = {**entry, **{n: round(float(t), 3) for n, t in times.items()}}
    path = _path()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".run_times-", suffix=".tmp")
        try:
            with os.fdopen(fd, "w") as f:
                json.dump(data, f, indent=1, sort_keys=True)
            os.replace(tmp, path)
        except BaseException:
            os.unlink(tmp)
            raise
    except OSError:
        pass
