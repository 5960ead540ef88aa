"""The two derivation paths (reference.formulations: "symbolic", "sums") measured on one model
each: the cold derivation, the warm start and the per-state cost, and on an MJCF file
Pinocchio's answer and cost at the same states.

Each measurement runs in a child process of its own (a fresh derivation cache for the cold
one; the same cache, read back, for the warm one), one at a time, within --budget seconds of
wall time (a derivation past it is reported as not finished). Models:

    textbook:NAME   a built-in model (reference.models)
    a02:N           the IFToMM A02 N-four-bar (examples/a02/nfourbar.py)
    cassie          Cassie, Pinocchio's closed-chain model (tests/data/real/pinocchio_cassie.xml)
    file:PATH       an MJCF file

    python benchmarks/derivation_paths.py cassie a02:10 a02:20 a02:40 --paths sums
    python benchmarks/derivation_paths.py textbook:double_pendulum_3d a02:5 --paths symbolic,sums
    python benchmarks/derivation_paths.py --size textbook:top_cartesian a02:5 cassie
    python benchmarks/derivation_paths.py --agreement
    python benchmarks/derivation_paths.py a02:10 file:tests/data/spatial_mix.xml --profile \
        --paths symbolic,sums --no-pinocchio

Per row: the model's size (reference.formulations.model_size), the cold time (the file's
import, the derivation, the generated code, loaded: a NumericModel of the model's first
formulation), the warm start (a new process: the import and the NumericModel read back from
the cache), and on MJCF files the per-state cost of the reference's checked forward call, of
Pinocchio through the suite's adapter (crosscheck.engines.pinocchio.user_file) and of
Pinocchio's own constraintDynamics on the same model and states, with the largest differences
from the reference (u' scaled by max(1, |u'|), the loop multipliers by max(1, |lambda|)).
--profile: the cold derivation's stages under cProfile (cumulative seconds, profiled).
--agreement: the two paths' M, f, A, b, u' and lambda on every built-in model and formulation
at the run's consistent states (path_agreement). Figures: benchmarks/scaling.md, "Two
derivation paths".
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # the checkout: reference, crosscheck and benchmarks
# one BLAS thread, before numpy loads (as examples/a02/scaling.py: on the shared 2-core
# machine two threads made the small solves many times slower)
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
STATES = 4  # states per MJCF file: the initial one and seeded consistent ones
TIMING_S = 1.0  # wall time over which a per-state cost is averaged

CHILD = r"""
import cProfile, json, os, sys, time
t0 = time.perf_counter()
sys.path.insert(0, {root!r})
from benchmarks.derivation_paths import load_model, profiled
model = load_model({spec!r})
t1 = time.perf_counter()
from reference.numeric.model import NumericModel
profile = cProfile.Profile() if {profile!r} else None
if profile:
    profile.enable()
nm = NumericModel(model)
t2 = time.perf_counter()
print(json.dumps({{"import_s": t1 - t0, "numeric_model_s": t2 - t1, "total_s": t2 - t0,
    "n": nm.n, "m": nm.m, "rank": nm.rank, "backend": nm.backend,
    "lines": len(nm.source.splitlines()), "profile": profiled(profile)}}))
"""

# the stages a profile reports: (function, file it is defined in)
STAGES = (
    ("derive", "formulations/__init__.py"),
    ("split_linear", "eom.py"),
    ("generalized_inertia_minus_active", "projection.py"),
    ("constraint_set", "constraints.py"),
    ("generate_source", "codegen.py"),
    ("summed_module", "codegen.py"),
    ("cse", "cse_main.py"),
    ("doprint", "codeprinter.py"),
)


def profiled(profile) -> dict | None:
    """Cumulative seconds (profiled) of each of STAGES, and in all."""
    if profile is None:
        return None
    import pstats

    profile.disable()
    stats = pstats.Stats(profile)
    out = {"total": stats.total_tt}
    for (path, _line, name), (_cc, _nc, _tt, cumulative, _callers) in stats.stats.items():
        for stage, where in STAGES:
            if name == stage and path.endswith(where):
                out[stage] = max(out.get(stage, 0.0), cumulative)
    return out


def load_model(spec: str):
    """The reference Model of a spec (see the module docstring); MJCF files registered with
    the suite's user models, as `crosscheck run --model-file` does."""
    if spec.startswith("textbook:"):
        from reference import models

        return models.get(spec.split(":", 1)[1])
    from crosscheck.user_models import load_model_file, register_all

    path = _mjcf_path(spec)
    um = load_model_file(path)[0]
    register_all([um])
    return um.model


def _mjcf_path(spec: str) -> Path:
    """The MJCF file of an a02, cassie or file spec (written to the temporary directory)."""
    work = Path(tempfile.gettempdir()) / "derivation_paths"
    work.mkdir(exist_ok=True)
    if spec.startswith("file:"):
        return Path(spec.split(":", 1)[1]).resolve()
    if spec.startswith("a02:"):
        sys.path.insert(0, str(ROOT / "examples" / "a02"))
        from nfourbar import mjcf

        n = int(spec.split(":", 1)[1])
        text, name = mjcf(n), f"a02_nfourbar_{n}.xml"
    elif spec == "cassie":
        return ROOT / "tests" / "data" / "real" / "pinocchio_cassie.xml"
    else:
        raise SystemExit(f"unknown model {spec!r}: textbook:NAME, a02:N, cassie or file:PATH")
    path = work / name
    path.write_text(text)
    return path


def _child(spec: str, path: str, cache: Path, budget: float, profile: bool = False) -> dict:
    """One NumericModel built in a child process on `path` with cache `cache` (under cProfile:
    `profile`)."""
    env = dict(os.environ, CROSSCHECK_CACHE_DIR=str(cache), CROSSCHECK_DERIVATION=path)
    code = CHILD.format(root=str(ROOT), spec=spec, profile=profile)
    try:
        out = subprocess.run(
            [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=budget
        )
    except subprocess.TimeoutExpired:
        return {"finished": False, "budget_s": budget}
    if out.returncode:
        return {"finished": False, "error": out.stderr.strip().splitlines()[-1]}
    return {"finished": True, **json.loads(out.stdout.strip().splitlines()[-1])}


def per_call(fn, budget: float = TIMING_S) -> float:
    """Mean seconds of fn() over about `budget` seconds (at least 3 calls)."""
    fn()
    k, t0 = 0, time.perf_counter()
    while k < 3 or time.perf_counter() - t0 < budget:
        fn()
        k += 1
    return (time.perf_counter() - t0) / k


def _cache(spec: str, path: str) -> Path:
    """The derivation cache of one model on one path (emptied by `derivation`)."""
    slug = "".join(c if c.isalnum() else "_" for c in spec)
    return Path(tempfile.gettempdir()) / "derivation_paths" / f"cache-{slug}-{path}"


def derivation(spec: str, path: str, budget: float, profile: bool = False) -> dict:
    """Cold (an empty cache; under cProfile: `profile`), then warm (the same cache), on one
    path."""
    cache = _cache(spec, path)
    shutil.rmtree(cache, ignore_errors=True)
    cache.mkdir(parents=True)
    cold = _child(spec, path, cache, budget, profile)
    warm = _child(spec, path, cache, budget) if cold["finished"] else None
    return {"model": spec, "path": path, "cold": cold, "warm": warm}


def per_state(spec: str, path: str) -> dict:
    """The reference's per-state cost and Pinocchio's at the same states, with their
    differences (an MJCF spec; the derivation cached by `derivation` or derived here)."""
    os.environ["CROSSCHECK_DERIVATION"] = path
    os.environ["CROSSCHECK_CACHE_DIR"] = str(_cache(spec, path))  # derived by `derivation`
    import numpy as np

    from benchmarks.pinocchio_loops import PinLoops
    from crosscheck.checks.sampling import consistent_states
    from crosscheck.engines.pinocchio.user_file import UserFilePinModel
    from reference.numeric.model import NumericModel

    model = load_model(spec)
    nm = NumericModel(model)
    adapter = UserFilePinModel(model.name)
    loops = PinLoops(adapter)
    err = {"adapter_u": 0.0, "adapter_lambda": 0.0, "constraint_dynamics_u": 0.0}
    states = consistent_states(nm, STATES)
    for q, u in states:
        ref = nm.forward(q, u)
        ad = adapter.forward(q, u)
        rows = list(ad.multiplier_rows if ad.multiplier_rows is not None else range(nm.m))
        scale_u = max(1.0, float(np.max(np.abs(ref.accelerations))))
        scale_l = max(1.0, float(np.max(np.abs(ref.multipliers[rows]))))
        err["adapter_u"] = max(
            err["adapter_u"], _worst(ad.accelerations, ref.accelerations) / scale_u
        )
        err["adapter_lambda"] = max(
            err["adapter_lambda"], _worst(ad.multipliers[rows], ref.multipliers[rows]) / scale_l
        )
        err["constraint_dynamics_u"] = max(
            err["constraint_dynamics_u"],
            loops.error(q, u, ad.raw["engine_accelerations"]) / scale_u,
        )
    q, u = states[0]
    mats = nm.kernels.function("matrices")
    out = np.empty(nm.kernels.total["matrices"])
    cost = {
        "reference_forward": per_call(lambda: nm.forward(q, u)),
        "reference_matrices": per_call(lambda: mats(q, u, 0.0, nm.kernel_parameters, out)),
        "pinocchio_adapter": per_call(lambda: adapter.forward(q, u)),
        "pinocchio_constraint_dynamics": per_call(loops.timed(q, u)),
    }
    return {"model": spec, "path": path, "states": len(states), "cost_s": cost, "error": err}


@contextlib.contextmanager
def on_path(path: str):
    """CROSSCHECK_DERIVATION set to `path` while models are built (reference.formulations)."""
    old = os.environ.get("CROSSCHECK_DERIVATION")
    os.environ["CROSSCHECK_DERIVATION"] = path
    try:
        yield
    finally:
        if old is None:
            os.environ.pop("CROSSCHECK_DERIVATION")
        else:
            os.environ["CROSSCHECK_DERIVATION"] = old


def path_agreement(model, formulation: str, states: int = 6) -> dict:
    """The sums path against the symbolic one on one model and formulation at the run's
    consistent states (crosscheck.checks.sampling): the largest scaled error (max |sums -
    symbolic| / max(1, max |symbolic|)) of M, f, A, b and of u', lambda. Both on the Python
    backend."""
    from crosscheck.checks.sampling import consistent_states
    from crosscheck.checks.tolerances import scaled_error
    from reference.numeric.model import NumericModel

    with on_path("symbolic"):
        sym = NumericModel(model, formulation, backend="python")
    with on_path("sums"):
        summed = NumericModel(model, formulation, backend="python")
    worst = dict.fromkeys(("M", "f", "A", "b", "accelerations", "multipliers"), 0.0)
    for q, u in consistent_states(sym, states):
        pairs = zip(("M", "f", "A", "b"), summed.matrices(q, u), sym.matrices(q, u), strict=True)
        a, b = summed.forward(q, u), sym.forward(q, u)
        pairs = [*pairs, ("accelerations", a.accelerations, b.accelerations)]
        pairs.append(("multipliers", a.multipliers, b.multipliers))
        for key, x, y in pairs:
            worst[key] = max(worst[key], scaled_error(x, y))
    return worst


def agreement_rows() -> list[dict]:
    """path_agreement on every built-in model and formulation, printed as it goes."""
    from reference import models

    rows = []
    for name in models.names():
        for formulation in models.get(name).formulations:
            worst = path_agreement(models.get(name), formulation)
            rows.append({"model": name, "formulation": formulation, **worst})
            print(json.dumps(rows[-1]), flush=True)
    return rows


def _worst(a, b) -> float:
    import numpy as np

    d = np.abs(np.asarray(a, float) - np.asarray(b, float))
    return float(d.max()) if d.size else 0.0


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("models", nargs="*")
    ap.add_argument(
        "--agreement",
        action="store_true",
        help="the sums path against the symbolic one on every built-in model and formulation",
    )
    ap.add_argument("--paths", default="sums", help="symbolic, sums or both (comma-separated)")
    ap.add_argument("--budget", type=float, default=600.0, help="wall seconds per derivation")
    ap.add_argument("--size", action="store_true", help="only the models' sizes")
    ap.add_argument("--profile", action="store_true", help="the cold derivation under cProfile")
    ap.add_argument("--no-pinocchio", action="store_true", help="no per-state comparison")
    ap.add_argument("--out", type=Path, help="append the rows to this JSON file")
    args = ap.parse_args(argv)
    rows = agreement_rows() if args.agreement else []
    for spec in args.models:
        if args.size:
            from reference.formulations import model_size

            model = load_model(spec)
            rows.append({"model": spec, "size": model_size(model), "n": len(model.speeds)})
            print(json.dumps(rows[-1]), flush=True)
            continue
        for path in args.paths.split(","):
            rows.append(derivation(spec, path, args.budget, args.profile))
            print(json.dumps(rows[-1]), flush=True)
            if rows[-1]["cold"]["finished"] and not spec.startswith("textbook:"):
                if not args.no_pinocchio:
                    rows.append(per_state(spec, path))
                    print(json.dumps(rows[-1]), flush=True)
    if args.out:
        old = json.loads(args.out.read_text()) if args.out.exists() else []
        command = "python benchmarks/derivation_paths.py " + " ".join(argv or sys.argv[1:])
        args.out.write_text(json.dumps([*old, {"command": command, "rows": rows}], indent=1))


if __name__ == "__main__":
    main()
