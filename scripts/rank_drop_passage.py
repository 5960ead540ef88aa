"""Why the reference does not integrate through a rank drop (docs/scaling.md, "What is not done").

The IFToMM A02 N-four-bar (examples/a02/nfourbar.py) is run over 10 s at the suite's rtol 1e-12
with a KKT solve that, instead of refusing a state where the loop rows lose rank, drops every
row direction whose singular value is below CUT x the largest and goes on. Per N and CUT it
prints where the run ended (or why it stopped), the energy drift, the crank spread (0 on the
parallelogram motion) and, over the evaluations that dropped a direction, the largest
acceleration the dropped rows ask for (|U_d^T b| / sigma_d) against the largest |u'|.

    PYTHONPATH=$PWD python scripts/rank_drop_passage.py            # N = 1, 2, 5; CUT 1e-6, 1e-4

The solve here is an experiment, not the reference's (reference.numeric.redundant refuses the
state).
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "examples" / "a02"))
from nfourbar import mjcf

from reference.integrate.driver import simulate
from reference.mjcf.loader import import_mjcf
from reference.numeric.model import NumericModel


def dropping_solve(nm: NumericModel, cut: float, seen: dict):
    """forward_raw's numeric solve with directions below `cut` dropped; `seen` collects the
    dropped rows' implied accelerations and |u'|."""
    n, m = nm.n, nm.m

    def solve(q, u, t, db=None):
        M, f, A, b = (np.asarray(x, float) for x in nm._scalar_call("matrices", q, u, t))
        M, A = M.reshape(n, n), A.reshape(m, n)
        U, s, Vt = np.linalg.svd(A)
        r = int((s > cut * s[0]).sum())
        Ar = s[:r, None] * Vt[:r]
        K = np.block([[M, -Ar.T], [Ar, np.zeros((r, r))]])
        x = np.linalg.solve(K, np.concatenate([f, U[:, :r].T @ b]))
        ud, mu = x[:n], x[n:]
        if r < nm.rank:
            d = np.arange(r, nm.rank)
            seen["implied"] = max(seen["implied"], float(np.max(np.abs(U[:, d].T @ b) / s[d])))
            seen["drops"] += 1
        seen["ud"] = max(seen["ud"], float(np.max(np.abs(ud))))
        return ud.tolist(), (U[:, :r] @ mu).tolist(), 1.0

    return solve


def run(n_cells: int, cut: float, work: Path) -> str:
    path = work / f"a02_{n_cells}.xml"
    path.write_text(mjcf(n_cells))
    nm = NumericModel(import_mjcf(path).model, "kane")
    seen = {"implied": 0.0, "drops": 0, "ud": 0.0}
    nm._forward_redundant = dropping_solve(nm, cut, seen)  # this instance only
    q0, u0 = np.array(nm.model.initial_q, float), np.array(nm.model.initial_u, float)
    try:
        tr = simulate(nm, q0, u0, 10.0, rtol=1e-12, atol=1e-12)
    except Exception as exc:  # the finding: where and why the run stopped
        end = f"stopped: {type(exc).__name__}: {str(exc).splitlines()[0][:90]}"
        figures = ""
    else:
        E = [sum(nm.energy(q, u)) for q, u in zip(tr.q, tr.u, strict=True)]
        spread = float(np.max(np.ptp(tr.q[:, 0::2], axis=1)))
        end = f"reached t = {tr.t[-1]:g} s"
        figures = f", energy drift {np.ptp(E):.2e} J, crank spread {spread:.1e} rad"
    return (
        f"N = {n_cells}, cut {cut:g}: {end}{figures}; {seen['drops']} evaluations dropped a "
        f"direction, implied acceleration up to {seen['implied']:.2e} against |u'| <= "
        f"{seen['ud']:.2e}"
    )


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        for cut in (1e-6, 1e-4):
            for n_cells in (1, 2, 5):
                print(run(n_cells, cut, Path(tmp)), flush=True)


if __name__ == "__main__":
    main()
