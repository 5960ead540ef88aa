"""The Exudyn system of a user's MJCF file, built from MuJoCo's compiled model
(crosscheck.engines.compiled_model: the numbers the reference is built from), element by element:

- hinges and slides are the joints of one ObjectKinematicTree (minimal coordinates, on one
  NodeGenericODE2): each joint is a link whose frame sits at the joint's anchor with its z axis
  along the compiled axis (RevoluteZ / PrismaticZ), placed in its parent link's frame by
  jointOffsets and jointTransformations (the rotation's columns are the link's axes in the
  parent's, measured); the coordinate is qpos - qpos0, the angle or offset as mj_kinematics
  reads it. A body with several joints is a chain of links (massless but the last), composed
  in MuJoCo's order; a body without joints is merged into its carrier's inertia (mass, mass
  centre and inertia combined exactly in the carrier's frame); bodies fixed to the world only
  add their constant weight to the potential;
- a free joint is an Euler-parameter body (NodeRigidBodyEP at the body's frame origin,
  ObjectRigidBody with the inertia about that point): its coordinates are MuJoCo's qpos and
  its Euler parameters' rates the quaternion rates; a ball joint on a body whose parent is
  fixed to the world is the same body held by an ObjectJointSpherical at the anchor;
- a ball or free joint with joints below it (a floating-base robot), or a ball joint on a
  moving body, is links of the tree instead, so the joints below stay minimal coordinates with
  their armature, springs, dampers and actuators: three prismatic links along the world axes
  (free) and three revolute links about x, y, z of a base rotation re-based at every mapped
  state (euler_links.py); its damping is on those links' rates (exact at zero angles);
- gravity: the tree's own gravity vector and LoadMassProportional on the rigid bodies;
  armature, stiffness (about springref), damping and the actuators at their stated controls
  on hinges and slides: one ObjectGenericODE2 on the tree's coordinates, M th'' + D th' + K th
  = f (an actuator's force is affine in its joints' qpos and qvel, coupled over a fixed
  tendon's joints);
- connect and weld: an ObjectJointGeneric between markers at the two compiled frames (on the
  tree's links, MarkerKinematicTreeRigid, or on the rigid bodies, their localHT the frame),
  its axes those of the first; joint: an ObjectConnectorCoordinateVector on the tree's
  coordinates, q1 - c1 q2 - c2 q2^2 = c0 (the joints' offsets from qpos0).

Dependent rows. Exudyn's initial-acceleration solve needs a regular KKT matrix (with a
dependent row it falls back to zero accelerations and says so on the console), so each
connect's or weld's axes are chosen once, at the file's initial state: MuJoCo's rows in the
first frame's axes (ObjectJointGeneric constrains the J0 components of a partly constrained
translation) are taken greedily, largest independent part first, until the rank of all rows is
reached (pivoted Gram-Schmidt); the axes left free are dependent there (a planar loop's
out-of-plane axis, fixed in the frame as the loop moves).

Not built, each named in the skip record: a ball or free joint beside other joints, armature
on a ball or free joint, damping on one of the Euler-parameter bodies, and a joint equality
beyond quadratic (ObjectConnectorCoordinateVector has linear and quadratic terms).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import exudyn as exu
import numpy as np
from exudyn.itemInterface import (
    LoadMassProportional,
    MarkerBodyMass,
    MarkerBodyRigid,
    MarkerKinematicTreeRigid,
    MarkerNodeCoordinates,
    NodeGenericODE2,
    NodeRigidBodyEP,
    ObjectConnectorCoordinateVector,
    ObjectGenericODE2,
    ObjectGround,
    ObjectJointGeneric,
    ObjectJointSpherical,
    ObjectKinematicTree,
    ObjectRigidBody,
)

from crosscheck.engines.compiled_model import CompiledModel, Equality, joint_frame
from crosscheck.engines.user_file_model import RANK_RTOL

__all__ = ["Carrier", "Link", "SystemBuilder", "rank_of", "refusals"]


@dataclass
class Carrier:
    """What a body is fixed to in the Exudyn model: the world (kind "world"), a tree link or
    an Euler-parameter body (``index``: the link's, or the ball or free joint's), and the
    inertia gathered in its frame (mass, first moment, second moment about the origin)."""

    kind: str
    index: int = -1
    mass: float = 0.0
    first: np.ndarray = field(default_factory=lambda: np.zeros(3))
    second: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))

    def add(self, mass: float, com, inertia) -> None:
        """A rigid body's inertia (about its mass centre ``com``, both in this frame)."""
        c = np.asarray(com, float)
        self.mass += mass
        self.first = self.first + mass * c
        self.second = self.second + inertia + mass * (c @ c * np.eye(3) - np.outer(c, c))

    def central(self) -> tuple[float, np.ndarray, np.ndarray]:
        """(mass, mass centre, inertia about the mass centre) of what was added."""
        if self.mass == 0.0:
            return 0.0, np.zeros(3), self.second.copy()
        c = self.first / self.mass
        return self.mass, c, self.second - self.mass * (c @ c * np.eye(3) - np.outer(c, c))


@dataclass
class Link:
    """One ObjectKinematicTree link: a hinge or slide of MuJoCo joint ``joint`` (along its
    z axis), or one of a ball or free joint's links (along ``axis``)."""

    parent: int
    offset: np.ndarray
    rotation: np.ndarray
    slide: bool
    joint: int
    carrier: Carrier
    axis: int = 2

    def joint_type(self):
        """Exudyn's joint type of this link."""
        return getattr(
            exu.JointType, ("Prismatic" if self.slide else "Revolute") + "XYZ"[self.axis]
        )


def refusals(cm: CompiledModel) -> list[str]:
    """What this builder does not express in a compiled model.

    Parameters
    ----------
    cm : CompiledModel

    Returns
    -------
    list of str
        One sentence per element: the element, and why (module docstring).
    """
    out = []
    for b in cm.bodies:
        kinds = [j.kind for j in b.joints]
        spatial = [j for j in b.joints if j.kind in ("ball", "free")]
        if spatial and len(kinds) > 1:
            out.append(
                f"{spatial[0].kind} joint {spatial[0].name!r} on body {b.name!r} beside other "
                "joints: this builder keeps a ball or free joint alone on its body (an "
                "Euler-parameter body, or Euler-angle links of the tree)"
            )
        tree = bool(spatial) and in_tree(cm, b)
        for j in spatial:
            if np.any(j.armature) or (np.any(j.damping) and not tree):
                what = "armature" if np.any(j.armature) else "damping"
                out.append(
                    f"{what} on {j.kind} joint {j.name!r}: MuJoCo's acts on the joint's "
                    "relative angular velocity in the child's frame, which an Exudyn rigid "
                    "body's inertia (absolute angular velocity) does not express"
                    + (
                        ", nor a constant mass matrix on the tree's Euler angles (its rates' "
                        "velocity terms)"
                        if tree
                        else ""
                    )
                )
    for e in cm.equalities:
        if e.kind == "joint" and e.polycoef is not None and np.any(e.polycoef[3:]):
            out.append(
                f"joint equality {e.name!r} is cubic or quartic: Exudyn's "
                "ObjectConnectorCoordinateVector has linear and quadratic terms only"
            )
    return out


def in_tree(cm: CompiledModel, b) -> bool:
    """Whether body b's ball or free joint is links of the tree (module docstring): it is on a
    moving body, or a body below it has a joint."""
    return cm.moving(b.parent) or _carries_joints(cm, b.index)


def _carries_joints(cm: CompiledModel, index: int) -> bool:
    """Whether a body below body ``index`` has a joint."""
    below = {index}
    for b in cm.bodies:  # parents come before their children
        if b.parent in below and b.index != index:
            below.add(b.index)
            if b.joints:
                return True
    return False


class SystemBuilder:
    """Mixed into Exudyn's model of a user's file (crosscheck.engines.exudyn.user_file, which
    gives ``mbs``, ``cm``, ``gravity`` and the maps of user_file_model): ``_build`` puts the
    compiled model into ``mbs`` (module docstring) and chooses the dependent rows' axes."""

    def _build(self) -> None:
        mbs, cm = self.mbs, self.cm
        self.ground = mbs.AddObject(ObjectGround())
        self.carriers: dict[int, tuple[Carrier, np.ndarray, np.ndarray]] = {
            0: (Carrier("world"), np.eye(3), np.zeros(3))
        }
        self.links: list[Link] = []
        self.ep: dict[int, tuple[int, int, Carrier]] = {}  # MuJoCo joint -> (node, body, carrier)
        self.static_potential = 0.0
        self.com_markers: list[tuple[float, int]] = []  # (mass, marker at its mass centre)
        self.ball_frames: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        # a tree ball or free joint -> (its first revolute link, base axes); its base rotation
        self.euler: dict[int, tuple[int, np.ndarray]] = {}
        self.euler_base: dict[int, np.ndarray] = {}
        for b in cm.bodies:
            self._place(b)
        self._tree_objects()
        self._rigid_bodies()
        self._passive()
        self._equalities()
        self._select_rows()

    def _place(self, b) -> None:
        """Put body b on its carrier (module docstring): new links for hinges and slides, an
        Euler-parameter body for a ball or free joint, its parent's carrier otherwise."""
        carrier, R, p = self.carriers[b.parent]
        R, p = R @ b.rot, p + R @ b.pos  # the body frame before its joints, in the carrier
        for j in b.joints:
            if j.kind in ("ball", "free") and in_tree(self.cm, b):
                carrier, R, p = self._euler_links(j, carrier, R, p)
                continue
            if j.kind in ("ball", "free"):
                if j.kind == "ball":  # the parent is fixed to the world: R, p are world axes
                    self.ball_frames[j.index] = (R, p)
                carrier = Carrier("ep", j.index)
                self.ep[j.index] = (-1, -1, carrier)
                R, p = np.eye(3), np.zeros(3)  # the node sits at the body frame's origin
                continue
            A = joint_frame(j.axis)
            parent = carrier.index if carrier.kind == "link" else -1
            carrier = Carrier("link", len(self.links))
            self.links.append(
                Link(parent, p + R @ j.anchor, R @ A, j.kind == "slide", j.index, carrier)
            )
            R, p = A.T, -A.T @ j.anchor  # the body frame in the new link's frame
        self.carriers[b.index] = (carrier, R, p)
        if carrier.kind == "world":
            self.static_potential -= b.mass * float(self.cm.gravity @ (p + R @ b.com))
        else:
            carrier.add(b.mass, p + R @ b.com, R @ b.inertia @ R.T)

    def _euler_links(self, j, carrier, R, p) -> tuple[Carrier, np.ndarray, np.ndarray]:
        """A ball or free joint as tree links (euler_links.py); the body frame in the last."""
        parent = carrier.index if carrier.kind == "link" else -1
        if j.kind == "free":  # a top-level body: its frame is qpos in world axes
            R, p = np.eye(3), np.zeros(3)
        slides = [(True, np.zeros(3), np.eye(3))] * (3 if j.kind == "free" else 0)
        turns = [(False, p + R @ j.anchor, R)] + [(False, np.zeros(3), np.eye(3))] * 2
        self.euler[j.index] = (len(self.links) + len(slides), R)
        self.euler_base[j.index] = np.eye(3)
        for k, (slide, offset, rotation) in enumerate(slides + turns):
            carrier = Carrier("link", len(self.links))
            self.links.append(Link(parent, offset, rotation, slide, j.index, carrier, k % 3))
            parent = carrier.index
        return carrier, np.eye(3), -np.asarray(j.anchor, float)

    def rebase(self, joint: int, quat_matrix) -> None:
        """Re-base a tree ball or free joint's angles at its rotation ``quat_matrix``."""
        first, R = self.euler[joint]
        self.links[first].rotation = R @ quat_matrix
        self.euler_base[joint] = np.array(quat_matrix, float)
        if self.links and int(self.tree) >= 0:
            self.mbs.SetObjectParameter(
                self.tree,
                "jointTransformations",
                exu.Matrix3DList([lk.rotation for lk in self.links]),
            )

    def _tree_objects(self) -> None:
        n = len(self.links)
        self.tree = self.tree_node = -1
        if not n:
            return
        mbs = self.mbs
        self.tree_node = mbs.AddNode(
            NodeGenericODE2(
                referenceCoordinates=[0.0] * n,
                initialCoordinates=[0.0] * n,
                initialCoordinates_t=[0.0] * n,
                numberOfODE2Coordinates=n,
            )
        )
        inertia = [lk.carrier.central() for lk in self.links]
        self.tree = mbs.AddObject(
            ObjectKinematicTree(
                nodeNumber=self.tree_node,
                gravity=list(self.cm.gravity),
                jointTypes=[lk.joint_type() for lk in self.links],
                linkParents=[lk.parent for lk in self.links],
                jointTransformations=exu.Matrix3DList([lk.rotation for lk in self.links]),
                jointOffsets=exu.Vector3DList([lk.offset for lk in self.links]),
                linkInertiasCOM=exu.Matrix3DList([I for _, _, I in inertia]),
                linkCOMs=exu.Vector3DList([c for _, c, _ in inertia]),
                linkMasses=[m for m, _, _ in inertia],
            )
        )
        # markers at the links' mass centres, for the potential energy
        self.com_markers += [
            (m, self._marker(Carrier("link", k), c)) for k, (m, c, _) in enumerate(inertia) if m
        ]

    def _rigid_bodies(self) -> None:
        mbs = self.mbs
        for j, (_, _, carrier) in list(self.ep.items()):
            mass, com, Ic = carrier.central()
            I0 = Ic + mass * (com @ com * np.eye(3) - np.outer(com, com))  # about the node
            node = mbs.AddNode(NodeRigidBodyEP(referenceCoordinates=[0.0, 0, 0, 1, 0, 0, 0]))
            body = mbs.AddObject(
                ObjectRigidBody(
                    mass=mass,
                    inertia=[I0[0, 0], I0[1, 1], I0[2, 2], I0[1, 2], I0[0, 2], I0[0, 1]],
                    centerOfMass=list(com),
                    nodeNumber=node,
                )
            )
            self.ep[j] = (node, body, carrier)
            if any(self.gravity):
                mbs.AddLoad(
                    LoadMassProportional(
                        markerNumber=mbs.AddMarker(MarkerBodyMass(bodyNumber=body)),
                        loadVector=list(self.gravity),
                    )
                )
            self.com_markers.append((mass, self._marker(Carrier("ep", j), com)))
            joint = self.cm.joint(j)
            if joint.kind == "ball":  # held at its anchor to the world (its parent is static)
                RF, pF = self.ball_frames[j]
                anchor = pF + RF @ joint.anchor
                mbs.AddObject(
                    ObjectJointSpherical(
                        markerNumbers=[
                            self._marker(Carrier("world"), anchor),
                            self._marker(Carrier("ep", j), joint.anchor),
                        ]
                    )
                )

    def _marker(self, carrier: Carrier, pos, rot=None) -> int:
        """A rigid marker at ``pos`` in a carrier's frame (the world, a link, a rigid body),
        its axes ``rot`` (carrier components; default the carrier's)."""
        mbs = self.mbs
        where = {"localHT": exu.HT(rotation=np.eye(3) if rot is None else rot, translation=pos)}
        if carrier.kind == "link":
            return mbs.AddMarker(
                MarkerKinematicTreeRigid(objectNumber=self.tree, linkNumber=carrier.index, **where)
            )
        body = self.ground if carrier.kind == "world" else self.ep[carrier.index][1]
        return mbs.AddMarker(MarkerBodyRigid(bodyNumber=body, **where))

    def _passive(self) -> None:
        """Armature, stiffness and damping of hinges and slides, and the actuators, on the
        tree's coordinates: M th'' + D th' + K th = f with th = qpos - qpos0."""
        n = len(self.links)
        if not n:
            return
        joints = [self.cm.joint(lk.joint) for lk in self.links]
        one = np.array([j.kind in ("hinge", "slide") for j in joints])
        # a ball's or free joint's damping per dof on its links' rates: exact where its angles
        # are zero (G = I), as every mapped state re-bases them (their armature is refused)
        dof = [
            k - min(i for i, o in enumerate(self.links) if o.joint == lk.joint)
            for k, lk in enumerate(self.links)
        ]
        M = np.diag(np.where(one, [j.armature[0] for j in joints], 0.0))
        K = np.diag(np.where(one, [j.stiffness for j in joints], 0.0))
        D = np.diag([j.damping[d] for j, d in zip(joints, dof, strict=True)])
        f = np.where(one, [j.stiffness * (j.springref - j.qpos0) for j in joints], 0.0)
        slot = {lk.joint: i for i, lk in enumerate(self.links) if one[i]}
        qpos0 = np.array([j.qpos0 for j in joints])
        for a in self.cm.actuators:  # k_i F, F = c + a_L sum k_j qpos_j + a_V sum k_j qvel_j
            k = np.zeros(n)
            for j, kj in a.terms:
                k[slot[j]] += kj
            K -= a.per_length * np.outer(k, k)
            D -= a.per_velocity * np.outer(k, k)
            f += k * (a.constant + a.per_length * float(k @ qpos0))
        if not (np.any(M) or np.any(K) or np.any(D) or np.any(f)):
            return
        self.mbs.AddObject(
            ObjectGenericODE2(
                nodeNumbers=[self.tree_node],
                massMatrix=M,
                stiffnessMatrix=K,
                dampingMatrix=D,
                forceVector=list(f),
            )
        )

    def _side_carrier(self, side) -> tuple[Carrier, np.ndarray, np.ndarray]:
        """The carrier of one side's frame and the frame's origin and axes in it."""
        carrier, R, p = self.carriers[side.body]
        return carrier, p + R @ side.pos, R @ side.rot

    def _equalities(self) -> None:
        mbs = self.mbs
        self.eq_objects: list[int] = []
        self.side_markers: list[tuple[int, ...]] = []
        for e in self.cm.equalities:
            if e.kind == "joint":
                self.eq_objects.append(self._joint_equality(e))
                continue
            # markers at the sides' frames: ObjectJointGeneric's axes are the first's
            sides = tuple(self._marker(*self._side_carrier(side)) for side in e.sides)
            self.side_markers.append(sides)
            rot = 1 if e.rows == 6 else 0
            self.eq_objects.append(
                mbs.AddObject(
                    ObjectJointGeneric(
                        markerNumbers=list(sides), constrainedAxes=[1, 1, 1, rot, rot, rot]
                    )
                )
            )

    def _joint_equality(self, e: Equality) -> int:
        mbs, n = self.mbs, len(self.links)
        index = {lk.joint: k for k, lk in enumerate(self.links)}
        c = e.polycoef
        assert c is not None
        lin, quad = np.zeros((1, n)), np.zeros((1, n))
        lin[0, index[e.joints[0]]] = 1.0
        if e.joints[1] >= 0:
            lin[0, index[e.joints[1]]] -= c[1]
            quad[0, index[e.joints[1]]] -= c[2]
        coords = [mbs.AddMarker(MarkerNodeCoordinates(nodeNumber=self.tree_node)) for _ in "01"]
        return mbs.AddObject(  # both markers on the tree's coordinates, the second unused
            ObjectConnectorCoordinateVector(
                markerNumbers=coords,
                scalingMarker0=lin,
                quadraticTermMarker0=quad,
                scalingMarker1=np.zeros((1, n)),
                quadraticTermMarker1=np.zeros((1, n)),
                offset=[float(c[0])],
            )
        )

    def _engine_axes(self, J, frames) -> np.ndarray:
        """MuJoCo's rows as Exudyn's connectors constrain them: a connect's or weld's position
        rows in its first frame's axes (ObjectJointGeneric's axes; the weld's rotation rows are
        in the second frame's, the first's on the manifold), a joint equality's as it is."""
        J, start = np.array(J, float), 0
        for e in self.cm.equalities:
            if e.kind != "joint":
                J[start : start + 3] = frames[e.index][0][0].T @ J[start : start + 3]
            start += e.rows
        return J

    def _select_rows(self) -> None:
        """Each connect's and weld's constrained axes, and whether each joint equality is kept,
        at the file's initial state (module docstring: dependent rows)."""
        cm = self.cm
        self.kept = np.ones(cm.rows, bool)
        if not cm.equalities:
            return
        self.mbs.Assemble()
        q0 = self.imp.model.initial_q  # type: ignore[attr-defined]
        qpos, qvel = self.mj_state(q0, np.zeros(self.n_ref))
        J = self.rows_jacobian(qpos)
        rank = rank_of(J)
        rows = self._engine_axes(J, self.frames_by_equality(qpos, qvel))
        self.kept = _greedy_rows(list(enumerate(rows)), rank, cm.rows)
        start = 0
        for e, obj in zip(cm.equalities, self.eq_objects, strict=True):
            keep = self.kept[start : start + e.rows]
            if e.kind == "joint":
                self.mbs.SetObjectParameter(obj, "activeConnector", bool(keep[0]))
            else:
                axes = [int(k) for k in keep] + [0] * (6 - e.rows)
                self.mbs.SetObjectParameter(obj, "constrainedAxes", axes)
            start += e.rows


def rank_of(J) -> int:
    """The rank of a matrix, singular values below RANK_RTOL of the largest cut.

    Parameters
    ----------
    J : array_like

    Returns
    -------
    int
    """
    s = np.linalg.svd(np.asarray(J, float), compute_uv=False) if np.size(J) else np.zeros(0)
    return int(np.sum(s > RANK_RTOL * s[0])) if s.size and s[0] > 0 else 0


def _greedy_rows(candidates, rank: int, m: int) -> np.ndarray:
    """Which of m rows to keep: repeatedly the candidate with the largest part outside the
    span of those kept (pivoted Gram-Schmidt), until ``rank`` are kept."""
    keep = np.zeros(m, bool)
    basis: list[np.ndarray] = []
    rows = {i: np.asarray(r, float) for i, r in candidates}
    while len(basis) < rank and rows:
        rest = {i: r - sum((b @ r) * b for b in basis) for i, r in rows.items()}
        i = max(rest, key=lambda k: float(np.linalg.norm(rest[k])))
        basis.append(rest[i] / np.linalg.norm(rest[i]))
        keep[i] = True
        del rows[i]
    return keep
