"""The "meta" every results file carries: the command, the package versions, the machine and
the date of the run that produced the numbers (run, bench and sweep write it; the report shows
it)."""

from __future__ import annotations

import platform
import time

import numpy as np
import sympy as sp


def meta(argv) -> dict:
    import scipy

    versions = {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "sympy": sp.__version__,
    }
    from crosscheck.engines.registry import engine_versions

    versions.update(engine_versions())  # keyed by distribution (e.g. "pin")
    import shlex

    return {
        "command": shlex.join(["crosscheck", *argv]),
        "versions": versions,
        "machine": {
            "platform": platform.platform(),
            "processor": platform.machine(),
            "cpus": __import__("os").cpu_count(),
        },
        "date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
