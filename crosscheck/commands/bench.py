"""`crosscheck bench`: forward-dynamics speed (crosscheck.bench.forward), work-precision,
stress scenes, the compiled stepper and the targets, written to DIR/bench.json."""

from __future__ import annotations

import sys
import time
from pathlib import Path

from crosscheck.bench.forward import PATHS, forward_ratios, forward_records
from crosscheck.runtime import jsonio
from crosscheck.runtime.provenance import meta


def _engines(requested):
    from crosscheck.engines.registry import get_engine

    return [get_engine(name) for name in requested]


def cmd_bench(args) -> int:
    from crosscheck.bench.skip_savings import skip_savings
    from crosscheck.bench.stress import stress_records
    from crosscheck.bench.targets import profile_for_missed, targets
    from crosscheck.bench.workprecision import work_precision_records
    from crosscheck.commands.arguments import output_dir, resolve_engines, resolve_models
    from crosscheck.runtime.output import write_atomic

    t_start = time.perf_counter()
    # the same rules as `run`: bad names exit 2 up front
    names = resolve_models(args.models, getattr(args, "user_models", None))
    requested = resolve_engines(args.engines)  # unknown or unimportable: exit 2
    engines = _engines(requested)
    output_dir(args.out)  # an unusable --out fails now, not after the benchmark
    out = Path(args.out)

    def log(msg):
        print(f"[{time.perf_counter() - t_start:6.1f} s] {msg}", file=sys.stderr, flush=True)

    result = {"meta": meta(sys.argv[1:]), "forward": forward_records(names, args.quick, engines)}
    from reference.backends import kernels, select

    # per generated module on the C backend: printing the C source, building it (c_build_s,
    # 0 when the cache held it) and importing it, and c_error where the printer or compiler
    # refused it (that module ran on the Python path)
    result["forward_ratios"] = forward_ratios(result["forward"])
    result["forward_paths"] = dict(PATHS)
    result["compiled"] = {
        "backend": select.backend(),
        "threads": select.threads(),
        "modules": dict(kernels.TIMINGS),
    }
    log("forward records done")
    from crosscheck.bench.derivatives import derivative_records

    # the reference's exact derivatives per state against Pinocchio's analytical ones
    result["derivatives"] = derivative_records(names, engines)
    log("derivative timings done")
    # engines by name: an adapter that cannot be imported gets rows marked skipped with the reason
    result["work_precision"] = work_precision_records(names, args.quick, requested, log=log)
    result["stress"] = stress_records(args.quick, log=log)
    tg = targets(result["forward"], result["work_precision"], quick=args.quick)
    profile_for_missed(tg)
    result["targets"] = tg
    result["skips"] = skip_savings(args.quick)
    log("targets and skip measurements done")
    from crosscheck.bench.stepper import stepper_records

    # the compiled stepper against the Python one, each model's runs timed side by side
    result["stepper"] = stepper_records(names, args.quick)
    log("stepper comparison done")
    result["meta"]["quick"] = bool(args.quick)
    result["failed_checks"] = failed_checks(result)
    result["meta"]["wall_s"] = time.perf_counter() - t_start
    write_atomic(out / "bench.json", jsonio.dumps(result))
    _print_summary(result, out)
    return 1 if result["failed_checks"] else 0


def failed_checks(result: dict) -> list[str]:
    """Every check of this bench that failed (the command then exits 1): a stress scene whose
    guard did not hold, a work-precision run or engine build that failed (an expected refusal,
    EngineUnsupported, is a skip with its reason, not a failure)."""
    out = [
        f"stress {r['scene']}: {'; '.join(r.get('reasons', []))[:300]}"
        for r in result.get("stress", [])
        if r.get("status") == "failed"
    ]
    out += [
        f"work-precision {r['model']} {r['engine']} {r.get('method')} {r.get('setting')}: "
        f"{str(r['failed'])[:300]}"
        for r in result.get("work_precision", [])
        if r.get("failed")
    ]
    out += [
        f"forward {r['model']} {r['engine']}: {r['failed']}"
        for r in result.get("forward", [])
        if r.get("failed")
    ]
    out += [
        f"stepper {r['model']} {r['method']} {r['outputs']}: {str(r['failed'])[:300]}"
        for r in result.get("stepper", [])
        if r.get("failed")
    ]
    return out


def _fmt_err(r) -> str:
    err = r.get("error")
    if err is None:
        return "None"
    return f"{err:.1e}" + ("" if r.get("error_resolved", True) else " (<= ref accuracy)")


def _print_summary(result: dict, out: Path) -> None:
    for r in result["forward"]:
        t = r["us_per_state"]
        print(
            f"{r['model']:22s} {r['engine']:10s} {r['path']:34s} {r['batch']:6d} "
            + (
                f"{t:10.3f} us/state"
                if t is not None
                else r.get("failed") or f"skipped: {r.get('reason') or r.get('skipped')}"
            )
        )
    print("\nreference paths")
    for path, what in result.get("forward_paths", {}).items():
        print(f"  {path:15s} {what}")
    print(
        "\nratios (targets: checked <= 0.5, raw <= 0.25 x Pinocchio; loop/batched >= 20;"
        " raw = single-raw, raw_out = single-raw-out, into = single-into)"
    )
    for r in result["forward_ratios"]:
        print(
            f"{r['model']:22s} ({r['backend']}) "
            + ", ".join(f"{k} {v:.2f}" for k, v in r.items() if isinstance(v, float))
        )
    print("\nwork-precision (model engine method setting: wall, error, residual)")
    for r in result["work_precision"]:
        head = (
            f"{r['model']:20s} {r['engine']:10s} {r.get('method')!s:20s} "
            f"{str(r.get('setting'))[:8]:8s}"
        )
        if r.get("wall_s") is None:
            print(
                f"{head} "
                + (f"skipped: {r.get('reason')}" if r.get("skipped") else str(r.get("failed")))
            )
        else:
            res = r.get("residual")
            print(
                f"{head} {r['wall_s'] * 1e3:9.2f} ms  err {_fmt_err(r)}"
                f"  res {res if res is None else f'{res:.1e}'}"
            )
    print("\nstress")
    for r in result["stress"]:
        print(f"  {r['scene']:24s} {r['status']}")
        for why in r.get("reasons", []):
            print(f"      - {why[:160]}")
    _print_targets(result["targets"])
    for why in result["failed_checks"]:
        print(f"FAILED {why}")
    print(
        f"\nwrote {out / 'bench.json'} in {result['meta']['wall_s']:.1f} s"
        + (f"; {len(result['failed_checks'])} check(s) failed" if result["failed_checks"] else "")
    )


def _print_targets(tg: dict) -> None:
    print("\ntargets")
    for key, t in tg.items():
        if "models" in t:
            print(
                f"  {key}: met={t.get('met')}"
                + (f" met_raw={t['met_raw']}" if "met_raw" in t else "")
            )
            for name, v in t["models"].items():
                raw = f" (unchecked path {v['ratio_raw']:.2f})" if v.get("ratio_raw") else ""
                print(f"      {name:20s} pinocchio/reference = {v['ratio']:.2f}{raw}")
        else:
            print(
                f"  {key}: met={t.get('met')} ratio={t.get('ratio')}"
                + (
                    f" met_speedup>={t['speedup_target']:g}={t['met_speedup']}"
                    if "met_speedup" in t
                    else ""
                )
                + (
                    f" ({t.get('compared_with') or t.get('reason')})"
                    if t.get("compared_with") or t.get("reason")
                    else ""
                )
            )


def register(sub):
    b = sub.add_parser("bench", help="benchmark forward dynamics (and work-precision)")
    from crosscheck.commands.arguments import add_engines, add_models

    add_models(b)
    b.add_argument("--quick", action="store_true")
    add_engines(b)
    b.add_argument("--out", default="out")
    b.set_defaults(func=cmd_bench)
