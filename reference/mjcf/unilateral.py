"""Contacts, limits and force clamps of an MJCF file: what acts at some states and not at others.

A contact acts only where two geoms touch, a joint or tendon limit only at the end of its range,
an actuator's force clamp only where the force reaches it. The reference has none of them (its
constraints are bilateral, its loads smooth), so a file that holds them is checked where none
acts, and refused only where one acts at every consistent state:

- ``present``: what the file holds: the geom pairs MuJoCo's broad phase would test
  (contype/conaffinity, same-body, parent-child and <exclude> filters; explicit <pair>s), the
  limited joints and tendons, the clamped actuator forces;
- ``Monitor.active(q, u)``: what acts at a reference state, by MuJoCo's own collision detection
  and constraint construction (mj_fwdPosition: a contact within the geoms' margins, a limit
  row), with a limited hinge or slide also required to lie strictly inside its range, and
  every clamped actuator force strictly inside its forcerange;
- ``always_in_contact``: contacts that act at every consistent state: two geoms that touch on
  bodies the equality constraints hold rigidly together (no motion the constraints allow
  moves one body relative to the other), which the import refuses.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import mujoco
import numpy as np

from reference.mjcf.checks import dense_efc_J, disabled, element
from reference.mjcf.speeds import qvel_from_rates

OBJ = mujoco.mjtObj
JNT = mujoco.mjtJoint
CNSTR = mujoco.mjtConstraint
# a relative motion of two bodies smaller than this times the Jacobians' size, in every
# direction the equality constraints allow, is none: the rows' null space from an SVD is exact
# to ~1e-15 relative, and any real freedom moves the bodies at order one
RIGID_TOL = 1e-9
# a limited coordinate is drawn this fraction of its range away from either end, so that the
# draw itself never lands on a limit
RANGE_INSET = 1e-3


def _geoms(m, g1: int, g2: int) -> str:
    return f"geom {element(m, OBJ.mjOBJ_GEOM, g1)!r} / geom {element(m, OBJ.mjOBJ_GEOM, g2)!r}"


def contact_pairs(m) -> list[str]:
    """Geom pairs MuJoCo's broad phase would test (contype/conaffinity, weld and parent
    filters, <exclude>), and explicit <pair>s, by name; empty when contacts are disabled."""
    if disabled(m, "mjDSBL_CONTACT") or disabled(m, "mjDSBL_CONSTRAINT"):
        return []
    excluded = {int(s) for s in m.exclude_signature[: m.nexclude]}
    weld, parent = m.body_weldid, m.body_parentid
    out = []
    for g1 in range(m.ngeom):
        for g2 in range(g1 + 1, m.ngeom):
            c1, a1 = m.geom_contype[g1], m.geom_conaffinity[g1]
            c2, a2 = m.geom_contype[g2], m.geom_conaffinity[g2]
            if not ((c1 & a2) or (c2 & a1)):
                continue
            b1, b2 = m.geom_bodyid[g1], m.geom_bodyid[g2]
            w1, w2 = weld[b1], weld[b2]
            if w1 == w2:
                continue  # same rigid group (or both static)
            if (
                not disabled(m, "mjDSBL_FILTERPARENT")
                and w1
                and w2
                and (w1 == weld[parent[w2]] or w2 == weld[parent[w1]])
            ):
                continue
            lo, hi = min(b1, b2), max(b1, b2)
            if (lo << 16) + hi in excluded or (hi << 16) + lo in excluded:  # MuJoCo's signature
                continue
            out.append(_geoms(m, g1, g2))
    out += [f"pair {_geoms(m, m.pair_geom1[p], m.pair_geom2[p])}" for p in range(m.npair)]
    return out


def _limits_on(m) -> bool:
    return not (disabled(m, "mjDSBL_LIMIT") or disabled(m, "mjDSBL_CONSTRAINT"))


class Activity(NamedTuple):
    """One element acting at a state: its kind ("contact", "limit" or "force limit") and what
    it is, in words."""

    kind: str
    what: str

    def __str__(self) -> str:
        return self.what


@dataclass(frozen=True)
class Present:
    """What a file holds that acts at some states only, by name."""

    contact_pairs: tuple[str, ...] = ()
    joint_limits: tuple[str, ...] = ()
    tendon_limits: tuple[str, ...] = ()
    force_limits: tuple[str, ...] = ()

    @property
    def limits(self) -> int:
        """Joint and tendon limits and force clamps together."""
        return len(self.joint_limits) + len(self.tendon_limits) + len(self.force_limits)

    def __bool__(self) -> bool:
        return bool(self.contact_pairs) or bool(self.limits)

    def summary(self) -> str:
        """E.g. '49 contact pairs, 17 joint limits' ('no contact pair or limit')."""
        parts = [
            (len(self.contact_pairs), "contact pair"),
            (len(self.joint_limits), "joint limit"),
            (len(self.tendon_limits), "tendon limit"),
            (len(self.force_limits), "actuator force clamp"),
        ]
        words = [f"{n} {w}{'s' if n != 1 else ''}" for n, w in parts if n]
        return ", ".join(words) if words else "no contact pair or limit"


def present(m, actuation) -> Present:
    """The contact pairs, limits and force clamps of a compiled model.

    Parameters
    ----------
    m : mujoco.MjModel
        The compiled file.
    actuation : reference.mjcf.actuators.Actuation
        The actuators that apply a force at their control (their clamps).

    Returns
    -------
    Present
    """
    limits = _limits_on(m)
    joints = [element(m, OBJ.mjOBJ_JOINT, j) for j in range(m.njnt) if limits and m.jnt_limited[j]]
    tendons = [
        element(m, OBJ.mjOBJ_TENDON, t) for t in range(m.ntendon) if limits and m.tendon_limited[t]
    ]
    forces = [f"actuator {a.name!r}" for a in actuation.joint if a.forcerange is not None]
    dofs = {dof for a in actuation.joint for dof, _adr, _k in a.terms}
    forces += [
        f"joint {element(m, OBJ.mjOBJ_JOINT, j)!r} (actuatorfrcrange)"
        for j in range(m.njnt)
        if m.jnt_actfrclimited[j] and int(m.jnt_dofadr[j]) in dofs
    ]
    return Present(tuple(contact_pairs(m)), tuple(joints), tuple(tendons), tuple(forces))


class Monitor:
    """What acts at a state of an imported file (see the module docstring)."""

    def __init__(self, m, joints, actuation, found: Present):
        self.m, self.joints, self.actuation, self.present = m, joints, actuation, found
        self.d = mujoco.MjData(m)
        limits = _limits_on(m)
        hinge_slide = (int(JNT.mjJNT_HINGE), int(JNT.mjJNT_SLIDE))
        # (joint, qpos address, lower, upper, margin) of every limited hinge and slide
        self.ranges = tuple(
            (j, int(m.jnt_qposadr[j]), *map(float, m.jnt_range[j]), float(m.jnt_margin[j]))
            for j in range(m.njnt)
            if limits and m.jnt_limited[j] and int(m.jnt_type[j]) in hinge_slide
        )

    def _state(self, q, u):
        q = np.asarray(q, float)
        return q, qvel_from_rates(self.joints, q, np.asarray(u, float), self.m.nv)

    def active(self, q, u) -> list[Activity]:
        """What acts at the reference state (q, u): contacts, limits and force clamps (empty:
        none)."""
        m, d = self.m, self.d
        qpos, qvel = self._state(q, u)
        d.qpos[:], d.qvel[:] = qpos, qvel
        mujoco.mj_fwdPosition(m, d)
        out = [
            Activity(
                "contact", f"{_geoms(m, c.geom1, c.geom2)} in contact (distance {c.dist:.3g} m)"
            )
            for c in d.contact[: d.ncon]
        ]
        rows = np.asarray(d.efc_type[: d.nefc])
        ids = np.asarray(d.efc_id[: d.nefc])
        at_limit = {int(i) for i in ids[rows == CNSTR.mjCNSTR_LIMIT_JOINT]}
        for j, adr, lo, hi, margin in self.ranges:
            if not lo + margin < qpos[adr] < hi - margin:
                at_limit.add(j)
        out += [
            Activity("limit", f"joint {element(m, OBJ.mjOBJ_JOINT, j)!r} at its limit")
            for j in sorted(at_limit)
        ]
        out += [
            Activity("limit", f"tendon {element(m, OBJ.mjOBJ_TENDON, int(t))!r} at its limit")
            for t in sorted(set(ids[rows == CNSTR.mjCNSTR_LIMIT_TENDON]))
        ]
        return out + self._clamped(qpos, qvel)

    def _clamped(self, qpos, qvel) -> list[Activity]:
        """Actuator forces at their forcerange, joints' actuator forces at their
        actuatorfrcrange."""
        m, out = self.m, []
        for a in self.actuation.joint:
            if a.forcerange is not None:
                lo, hi = a.forcerange
                if not lo < a.force(qpos, qvel) < hi:
                    out.append(Activity("force limit", f"actuator {a.name!r} at its force limit"))
        total = self.actuation.qfrc(qpos, qvel, m.nv)
        driven = {dof for a in self.actuation.joint for dof, _adr, _k in a.terms}
        for j in range(m.njnt):
            dof = int(m.jnt_dofadr[j])
            if m.jnt_actfrclimited[j] and dof in driven:
                lo, hi = (float(x) for x in m.jnt_actfrcrange[j])
                if not lo < total[dof] < hi:
                    name = element(m, OBJ.mjOBJ_JOINT, j)
                    out.append(
                        Activity("force limit", f"joint {name!r}'s actuator force at its limit")
                    )
        return out

    def clamped_to_ranges(self, q) -> np.ndarray:
        """q with every limited hinge and slide moved into its range (RANGE_INSET of the range,
        and its margin, from either end) where it lies outside."""
        q = np.array(q, float)
        for _j, adr, lo, hi, margin in self.ranges:
            inset = RANGE_INSET * (hi - lo) + margin
            if hi - lo > 2 * inset:
                q[adr] = min(max(q[adr], lo + inset), hi - inset)
        return q

    def inside_ranges(self, q, rng) -> np.ndarray:
        """q with every limited hinge and slide drawn uniformly inside its range (RANGE_INSET
        of the range, and its margin, away from either end)."""
        q = np.array(q, float)
        for _j, adr, lo, hi, margin in self.ranges:
            inset = RANGE_INSET * (hi - lo) + margin
            if hi - lo > 2 * inset:
                q[adr] = rng.uniform(lo + inset, hi - inset)
        return q


def _null_space(J: np.ndarray, nv: int) -> np.ndarray:
    """An orthonormal basis of the motions the rows J allow (nv x k)."""
    if J.shape[0] == 0:
        return np.eye(nv)
    _u, s, vt = np.linalg.svd(J)
    rank = int(np.sum(s > 1e-12 * max(float(s[0]), 1.0))) if s.size else 0
    return vt[rank:].T


def always_in_contact(m, qpos) -> list[tuple[str, str, str]]:
    """Contacts that act at every consistent state.

    Parameters
    ----------
    m : mujoco.MjModel
        The compiled file.
    qpos : array_like
        A consistent configuration (the initial state).

    Returns
    -------
    list of (str, str, str)
        (geom pair, body 1, body 2) of each contact there between bodies that no motion the
        equality constraints allow moves relative to each other (RIGID_TOL), once per pair.
    """
    if not contact_pairs(m):
        return []
    d = mujoco.MjData(m)
    d.qpos[:] = qpos
    mujoco.mj_forward(m, d)
    eq = np.asarray(d.efc_type[: d.nefc]) == CNSTR.mjCNSTR_EQUALITY
    N = _null_space(dense_efc_J(m, d)[eq], m.nv)
    out = []
    for c in d.contact[: d.ncon]:
        b1, b2 = int(m.geom_bodyid[c.geom1]), int(m.geom_bodyid[c.geom2])
        jac = []
        for b in (b1, b2):
            jp, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
            mujoco.mj_jac(m, d, jp, jr, np.asarray(c.pos, float), b)
            jac.append(np.vstack([jp, jr]))
        rel = jac[0] - jac[1]
        rigid = np.max(np.abs(rel @ N), initial=0.0) <= RIGID_TOL * max(1.0, np.max(np.abs(rel)))
        if rigid and _geoms(m, c.geom1, c.geom2) not in {o[0] for o in out}:
            out.append(
                (
                    _geoms(m, c.geom1, c.geom2),
                    element(m, OBJ.mjOBJ_BODY, b1),
                    element(m, OBJ.mjOBJ_BODY, b2),
                )
            )
    return out
