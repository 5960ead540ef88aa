"""`crosscheck engines [--json]`: every registered engine, its package version, what it can do,
and whether it imports here."""

from __future__ import annotations

import json

from crosscheck.engines.registry import engine_status


def cmd_engines(args) -> int:
    rows = engine_status()
    if args.json:
        print(json.dumps([r.as_dict() for r in rows], indent=2))
        return 0
    for r in rows:
        if not r.imports:
            print(f"{r.name:10s} does not import: {r.error}")
            continue
        caps = r.capabilities or {}
        can = [
            k
            for k in (
                "multipliers",
                "exact",
                "rigid_recovery",
                "mass_matrix",
                "nonholonomic",
                "variants",
                "soft_prediction",
                "soft_limit",
            )
            if caps.get(k)
        ]
        integ = ", ".join(caps.get("integrators", [])) or "none"
        print(
            f"{r.name:10s} {r.distribution} {r.version}  {len(r.models)} models  "
            f"[{', '.join(can)}]  integrators: {integ}"
        )
    return 0


def register(sub) -> None:
    e = sub.add_parser("engines", help="registered engines: version, capabilities, import state")
    e.add_argument("--json", action="store_true", help="machine-readable list")
    e.set_defaults(func=cmd_engines)
