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


def _finding(element, kind, text) -> dict:
    return {"element": element, "kind": kind, "finding": text}


def parser_findings(path, m) -> list[dict]:
    """[{"element", "kind", "finding"}] for the differences between pin's parse of `path` and
    MuJoCo's compiled model `m`; [] when the parser kept everything compared."""
    try:
        pm = pin.buildModelFromMJCF(str(path))
    except Exception as exc:
        message = " ".join(str(exc).split())
        return [_finding(str(path), "file", f"pin.buildModelFromMJCF fails: {message}")]
    body_frames = {f.name: f for f in pm.frames if f.type == pin.FrameType.BODY}
    jnames = list(pm.names)
    return (
        _missing_bodies(m, body_frames)
        + _joint_findings(pm, m, jnames)
        + _mass_findings(pm, m, body_frames, jnames)
        + _gravity_findings(pm, m)
        + _equality_findings(path, m)
    )


def _missing_bodies(m, body_frames) -> list[dict]:
    """MuJoCo's bodies that have no frame in the parsed model."""
    out = []
    for b in range(1, m.nbody):
        name = _name(m, mujoco.mjtObj.mjOBJ_BODY, b)
        if name not in body_frames:
            out.append(
                _finding(
                    name,
                    "body",
                    f"body {name} (mass {m.body_mass[b]:.6g}) is missing from the parsed model",
                )
            )
    return out


def _joint_findings(pm, m, jnames) -> list[dict]:
    """Every MuJoCo joint: missing from the parse, or (hinge, slide) its world axis at the
    neutral pose, armature, and the damping and stiffness pin's dynamics leave out."""
    out = []
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    pd = pm.createData()
    q0 = pin.neutral(pm)
    pin.computeJointJacobians(pm, pd, q0)
    for j in range(m.njnt):
        name = _name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
        if name not in jnames:
            out.append(_finding(name, "joint", f"joint {name} is missing from the parsed model"))
            continue
        jid = jnames.index(name)
        t = int(m.jnt_type[j])
        if t in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)):
            out += _dof_findings(pm, pd, m, d, j, jid, name)
    return out


def _dof_findings(pm, pd, m, d, j, jid, name) -> list[dict]:
    """One hinge or slide joint j (pin's joint jid): axis, armature, damping, stiffness."""
    out = []
    t = int(m.jnt_type[j])
    Jw = np.asarray(pin.getJointJacobian(pm, pd, jid, pin.ReferenceFrame.WORLD)).reshape(6, pm.nv)
    col = Jw[:, pm.idx_vs[jid]]
    axis = col[3:] if t == int(mujoco.mjtJoint.mjJNT_HINGE) else col[:3]
    if not _close(axis, d.xaxis[j]):
        out.append(
            _finding(
                name,
                "joint axis",
                f"joint {name}: parsed axis {np.round(axis, 9)} (world, "
                f"neutral pose), MuJoCo {np.round(d.xaxis[j], 9)}",
            )
        )
    adr = m.jnt_dofadr[j]
    if not _close(pm.armature[pm.idx_vs[jid]], m.dof_armature[adr]):
        out.append(
            _finding(
                name,
                "armature",
                f"joint {name}: parsed armature "
                f"{pm.armature[pm.idx_vs[jid]]:.6g}, MuJoCo "
                f"{m.dof_armature[adr]:.6g}",
            )
        )
    if m.dof_damping[adr]:
        out.append(
            _finding(
                name,
                "damping",
                f"joint {name}: damping {m.dof_damping[adr]:.6g} lands in "
                "model.damping, which pin's dynamics do not apply",
            )
        )
    if m.jnt_stiffness[j]:
        out.append(
            _finding(
                name,
                "stiffness",
                f"joint {name}: stiffness {m.jnt_stiffness[j]:.6g} (springref) is not parsed",
            )
        )
    return out


def _mass_findings(pm, m, body_frames, jnames) -> list[dict]:
    """Every parsed body's mass against MuJoCo's, compared on the body's joint."""
    out = []
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
            out.append(
                _finding(
                    name,
                    "mass",
                    f"body {name}: parsed mass on joint {jnames[jid]} "
                    f"{pm.inertias[jid].mass:.6g}, MuJoCo {mj_mass:.6g} (geom-derived "
                    "masses and inertias are not computed by the parser)",
                )
            )
    return out


def _gravity_findings(pm, m) -> list[dict]:
    """The parsed gravity against the file's (zero where the file disables gravity)."""
    g = (
        np.zeros(3)
        if m.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_GRAVITY)
        else np.array(m.opt.gravity, float)
    )
    if not _close(pm.gravity.linear, g):
        text = f"parsed gravity {pm.gravity.linear}, the file's {g}"
        return [_finding("option", "gravity", text)]
    return []


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
        message = " ".join(str(exc).split())
        text = f"pin.buildModelAndLegacyConstraintsFromMJCF fails: {message}"
        return [_finding("equality", "equality", text)]
    want = {"connect": pin.ContactType.CONTACT_3D, "weld": pin.ContactType.CONTACT_6D}
    got = [c.type for c in constraints]
    out = []
    for e in active:
        kind = kinds.get(int(m.eq_type[e]), "other")
        name = _name(m, mujoco.mjtObj.mjOBJ_EQUALITY, e)
        if kind in want and want[kind] in got:
            got.remove(want[kind])
            continue
        text = f"equality {kind} {name} has no constraint in the parsed model"
        out.append(_finding(name, "equality", text))
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

    from reference.mjcf.loader import compile_file

    print(json.dumps(parser_findings(sys.argv[1], compile_file(sys.argv[1]))))
