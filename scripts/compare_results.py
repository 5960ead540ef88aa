"""Two `crosscheck run` results.json files record by record (two commits' runs, or one
commit's on two machines): how many records differ in status (passed/skipped), how many errors
differ, and the largest error difference as a fraction of the record's tolerance, with the
record it is in. Both files must hold the same records in the same order.

    python scripts/compare_results.py A/results.json B/results.json
"""

from __future__ import annotations

import json
import sys


def main(a_path: str, b_path: str) -> None:
    a, b = (json.load(open(p))["records"] for p in (a_path, b_path))
    if len(a) != len(b):
        sys.exit(f"different record counts: {len(a)} and {len(b)}")
    status = errors = 0
    worst = (0.0, None)
    for x, y in zip(a, b, strict=True):
        key = tuple(x.get(k) for k in ("model", "formulation", "engine", "check", "quantity"))
        if key != tuple(y.get(k) for k in ("model", "formulation", "engine", "check", "quantity")):
            sys.exit(f"records out of order at {key}")
        status += (x.get("passed"), x.get("skipped")) != (y.get("passed"), y.get("skipped"))
        e1, e2, tol = x.get("error"), y.get("error"), x.get("tolerance")
        if e1 != e2:
            errors += 1
            if isinstance(e1, float) and isinstance(e2, float) and tol:
                worst = max(worst, (abs(e1 - e2) / tol, key), key=lambda w: w[0])
    print(f"{len(a)} records: {status} differ in status, {errors} in error")
    print(f"largest error difference: {worst[0]:.3g} of the tolerance ({worst[1]})")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
