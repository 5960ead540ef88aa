"""The reference's exact derivatives per state against Pinocchio's analytical ones, timed in
one run, interleaved (the rows `crosscheck bench` writes to bench.json `derivatives`):

    python benchmarks/derivative_speed.py [MODEL ...]      (default: every built-in model)
    python benchmarks/derivative_speed.py --model-file tests/data/real/pinocchio_cassie.xml

prints microseconds per state (medians over 15 interleaved rounds) of the reference's checked
call (DerivativeModel.at), its kernel alone, Pinocchio's forward call with its derivative
routine, and the checked call over Pinocchio's.
"""

from __future__ import annotations

import sys

from crosscheck.bench.derivatives import derivative_records
from crosscheck.engines.registry import get_engine
from reference import models


def main(names) -> None:
    rows = derivative_records(names, [get_engine("pinocchio")])
    by: dict = {}
    for r in rows:
        by.setdefault(r["model"], {})[r["path"]] = r
    print(f"{'model':24s} {'checked':>8s} {'kernel':>8s} {'pinocchio':>10s}  ratio  routine")
    for name, d in by.items():
        pin_row = d.get("pinocchio")
        kernel = d.get("reference-kernel", {}).get("us_per_state")
        print(
            f"{name:24s} {d['reference-checked']['us_per_state']:8.2f} "
            + (f"{kernel:8.2f} " if kernel is not None else f"{'-':>8s} ")
            + (
                f"{pin_row['us_per_state']:10.2f}  {d['ratio']['checked_over_pinocchio']:5.2f}"
                f"  {pin_row['call']}"
                if pin_row
                else f"{'-':>10s}      -  (no derivative routine: textbook rows as J, gamma)"
            )
        )


def _names(args: list[str]) -> list[str]:
    """The models named, and every model of each `--model-file PATH` (registered)."""
    from crosscheck.user_models import load_model_file, register_all

    names: list[str] = []
    while args:
        arg, *args = args
        if arg == "--model-file":
            path, *args = args
            names += register_all(load_model_file(path))
        else:
            names.append(arg)
    return names


if __name__ == "__main__":
    main(_names(sys.argv[1:]) or list(models.names()))
