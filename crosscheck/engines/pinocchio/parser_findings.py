"""What Pinocchio's own MJCF parser kept of a user's file, against MuJoCo's compiled model.

The dynamics cross-check never uses the parsed model (user_file builds a complete one from
MuJoCo's compiled numbers); this module says, element by element, what a user loading the
file with ``pin.buildModelFromMJCF`` would get wrong: bodies and joints missing, masses and
inertias, joint axes, gravity, armature, springs and dampers, equality constraints. Each
finding names the element; `crosscheck run` reports them as one record per model.
"""

from __future__ import annotations

import mujoco
import numpy as np

import pinocchio as pin

# relative size of a difference in mass, inertia, axis or gravity that is a finding: the
# parser reads the same decimal text MuJoCo does, so agreement is to round-off (1e-15); 1e-9
# leaves room for MuJoCo's own frame arithmetic and flags any real loss
REL = 1e-9


def _name(m, obj, i) -> str:
    return mujoco.mj_id2name(m, obj, i) or f"#{i}"


def _close(a, b) -> bool:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b), initial=0.0)) <= REL * max(
        1.0, float(np.max(np.abs(b), initial=0.0))
    )


def parser_findings(path, m) -> list[dict]:
    """[{"element", "kind", "finding"}] for the differences between pin's parse of `path` and
    MuJoCo's compiled model `m`; [] when the parser kept everything compared."""
    out: list[dict] = []

    def add(element, kind, text):
        out.append({"element": element, "kind": kind, "finding": text})

    try:
        pm = pin.buildModelFromMJCF(str(path))
    except Exception as exc:
        add(str(path), "file", f"pin.buildModelFromMJCF fails: {' '.join(str(exc).split())}")
        return out
    body_frames = {f.name: f for f in pm.frames if f.type == pin.FrameType.BODY}
    for b in range(1, m.nbody):
        name = _name(m, mujoco.mjtObj.mjOBJ_BODY, b)
        if name not in body_frames:
            add(
                name,
                "body",
                f"body {name} (mass {m.body_mass[b]:.6g}) is missing from the parsed model",
            )
    jnames = list(pm.names)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    pd = pm.createData()
    q0 = pin.neutral(pm)
    pin.computeJointJacobians(pm, pd, q0)
    for j in range(m.njnt):
        name = _name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
        if name not in jnames:
            add(name, "joint", f"joint {name} is missing from the parsed model")
            continue
        jid = jnames.index(name)
        t = int(m.jnt_type[j])
        if t in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)):
            Jw = np.asarray(pin.getJointJacobian(pm, pd, jid, pin.ReferenceFrame.WORLD)).reshape(
                6, pm.nv
            )
            col = Jw[:, pm.idx_vs[jid]]
            axis = col[3:] if t == int(mujoco.mjtJoint.mjJNT_HINGE) else col[:3]
            if not _close(axis, d.xaxis[j]):
                add(
                    name,
                    "joint axis",
                    f"joint {name}: parsed axis {np.round(axis, 9)} (world, "
                    f"neutral pose), MuJoCo {np.round(d.xaxis[j], 9)}",
                )
            adr = m.jnt_dofadr[j]
            if not _close(pm.armature[pm.idx_vs[jid]], m.dof_armature[adr]):
                add(
                    name,
                    "armature",
                    f"joint {name}: parsed armature "
                    f"{pm.armature[pm.idx_vs[jid]]:.6g}, MuJoCo "
                    f"{m.dof_armature[adr]:.6g}",
                )
            if m.dof_damping[adr]:
                add(
                    name,
                    "damping",
                    f"joint {name}: damping {m.dof_damping[adr]:.6g} lands in "
                    "model.damping, which pin's dynamics do not apply",
                )
            if m.jnt_stiffness[j]:
                add(
                    name,
                    "stiffness",
                    f"joint {name}: stiffness {m.jnt_stiffness[j]:.6g} (springref) is not parsed",
                )
    for b in range(1, m.nbody):
        name = _name(m, mujoco.mjtObj.mjOBJ_BODY, b)
        if name not in body_frames:
            continue
        f = body_frames[name]
        # the body's inertia as pin carries it: alone on its joint only when it is the
        # joint's first body; compare the mass there (a merged joint sums its bodies)
        jid = f.parentJoint
        mj_mass = sum(
            m.body_mass[c]
            for c in range(1, m.nbody)
            if _name(m, mujoco.mjtObj.mjOBJ_BODY, c) in body_frames
            and body_frames[_name(m, mujoco.mjtObj.mjOBJ_BODY, c)].parentJoint == jid
        )
        if jid and not _close(pm.inertias[jid].mass, mj_mass):
            add(
                name,
                "mass",
                f"body {name}: parsed mass on joint {jnames[jid]} "
                f"{pm.inertias[jid].mass:.6g}, MuJoCo {mj_mass:.6g} (geom-derived "
                "masses and inertias are not computed by the parser)",
            )
    g = (
        np.zeros(3)
        if m.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_GRAVITY)
        else np.array(m.opt.gravity, float)
    )
    if not _close(pm.gravity.linear, g):
        add("option", "gravity", f"parsed gravity {pm.gravity.linear}, the file's {g}")
    out += _equality_findings(path, m)
    return out


def _equality_findings(path, m) -> list[dict]:
    kinds = {
        int(mujoco.mjtEq.mjEQ_CONNECT): "connect",
        int(mujoco.mjtEq.mjEQ_WELD): "weld",
        int(mujoco.mjtEq.mjEQ_JOINT): "joint",
    }
    active = [e for e in range(m.neq) if m.eq_active0[e]]
    if not active:
        return []
    try:
        _pm, constraints = pin.buildModelAndLegacyConstraintsFromMJCF(str(path))[:2]
    except Exception as exc:
        return [
            {
                "element": "equality",
                "kind": "equality",
                "finding": f"pin.buildModelAndLegacyConstraintsFromMJCF fails: "
                f"{' '.join(str(exc).split())}",
            }
        ]
    want = {"connect": pin.ContactType.CONTACT_3D, "weld": pin.ContactType.CONTACT_6D}
    got = [c.type for c in constraints]
    out = []
    for e in active:
        kind = kinds.get(int(m.eq_type[e]), "other")
        name = _name(m, mujoco.mjtObj.mjOBJ_EQUALITY, e)
        if kind in want and want[kind] in got:
            got.remove(want[kind])
            continue
        out.append(
            {
                "element": name,
                "kind": "equality",
                "finding": f"equality {kind} {name} has no constraint in the parsed model",
            }
        )
    return out


def findings_isolated(path, timeout: float = 120.0) -> list[dict]:
    """parser_findings in a child process: pin's parser crashes the process (SIGSEGV) on some
    valid files (a site-based connect to a world site, tests/data/fourbar_sites.xml), and a
    crash is itself the finding."""
    import json
    import subprocess
    import sys

    proc = subprocess.run(
        [sys.executable, "-m", __name__, str(path)], capture_output=True, text=True, timeout=timeout
    )
    if proc.returncode == 0:
        return json.loads(proc.stdout)
    why = (
        f"signal {-proc.returncode}"
        if proc.returncode < 0
        else f"exit {proc.returncode}: {proc.stderr.strip().splitlines()[-1:]}"
    )
    return [
        {
            "element": str(path),
            "kind": "file",
            "finding": f"pin's MJCF parser crashes the process on this file ({why})",
        }
    ]


def summary(findings: list[dict]) -> str:
    """One line for a record: the count and the findings, most important first."""
    if not findings:
        return (
            "Pinocchio's MJCF parser kept every element compared (bodies, joints, axes, "
            "masses, gravity, armature, springs, dampers, equalities)"
        )
    return (
        f"{len(findings)} finding(s) on Pinocchio's own MJCF parse (the cross-check uses a "
        "Pinocchio model built from MuJoCo's compiled model instead): "
        + "; ".join(f["finding"] for f in findings)
    )


if __name__ == "__main__":
    import json
    import sys

    from reference.mjcf import compile_file

    print(json.dumps(parser_findings(sys.argv[1], compile_file(sys.argv[1]))))
