"""Cold build of the N-four-bar with the unrolled and with the numeric forward (the reason
for codegen.UNROLL_KKT_MAX): each in a fresh derivation cache, the unrolled one first.

    CROSSCHECK_BACKEND=python PYTHONPATH=$PWD python examples/a02/unroll_vs_numeric.py 5
"""

import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from nfourbar import mjcf

from reference.backends import codegen
from reference.mjcf.loader import import_mjcf
from reference.numeric.model import NumericModel

n = int(sys.argv[1]) if len(sys.argv) > 1 else 5
with tempfile.TemporaryDirectory() as tmp:
    path = Path(tmp) / "a02.xml"
    path.write_text(mjcf(n))
    imp = import_mjcf(path)
    for limit in (10**6, codegen.UNROLL_KKT_MAX):
        codegen.UNROLL_KKT_MAX = limit  # the entry records its choice in META['kkt']
        os.environ["CROSSCHECK_CACHE_DIR"] = os.path.join(tmp, f"cache_{limit}")
        codegen._TIDIED.clear()  # no trigsimp result carried over
        t0 = time.perf_counter()
        nm = NumericModel(imp.model, "kane")
        took = time.perf_counter() - t0
        print(
            f"N = {n}: {'numeric' if nm.numeric_kkt else 'unrolled'} forward, cold build "
            f"{took:.1f} s, generated source {len(nm.source) // 1000} kB",
            flush=True,
        )
