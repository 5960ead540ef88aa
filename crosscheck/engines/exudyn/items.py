"""Small builders of Exudyn items shared by the model modules (nodes at zero reference
coordinates, so every ODE2 coordinate is an absolute position or angle)."""

from __future__ import annotations

import exudyn as exu
import numpy as np
from exudyn.itemInterface import (
    LoadMassProportional,
    MarkerBodyMass,
    MarkerBodyPosition,
    MarkerBodyRigid,
    MarkerNodeCoordinate,
    NodePoint2D,
    NodePointGround,
    NodeRigidBody2D,
    ObjectGround,
    ObjectJointRevolute2D,
    ObjectMassPoint2D,
    ObjectRigidBody2D,
)


def ground(model) -> int:
    """The ground object (markers on it are fixed points of the world)."""
    return model.mbs.AddObject(ObjectGround())


def _gravity(model, body: int) -> None:
    g = list(model.gravity)
    if any(g):
        model.mbs.AddLoad(
            LoadMassProportional(
                markerNumber=model.mbs.AddMarker(MarkerBodyMass(bodyNumber=body)), loadVector=g
            )
        )


def point_mass_2d(model, mass: float) -> tuple[int, int]:
    """NodePoint2D (x, y) + ObjectMassPoint2D with gravity; returns (node, body)."""
    n = model.mbs.AddNode(NodePoint2D(referenceCoordinates=[0.0, 0.0]))
    b = model.mbs.AddObject(ObjectMassPoint2D(mass=mass, nodeNumber=n))
    _gravity(model, b)
    model.masses.append((n, b, mass))
    return n, b


def rigid_body_2d(model, mass: float, inertia: float) -> tuple[int, int]:
    """NodeRigidBody2D (x_G, y_G, phi) + ObjectRigidBody2D (inertia about G) with gravity."""
    n = model.mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[0.0, 0.0, 0.0]))
    b = model.mbs.AddObject(ObjectRigidBody2D(mass=mass, inertia=inertia, nodeNumber=n))
    _gravity(model, b)
    model.masses.append((n, b, mass))
    return n, b


def point(model, body: int, x: float = 0.0, y: float = 0.0, z: float = 0.0) -> int:
    """A position marker at local (x, y, z) of a body (or the ground)."""
    return model.mbs.AddMarker(MarkerBodyPosition(bodyNumber=body, localPosition=[x, y, z]))


def hinge_2d(model, marker0: int, marker1: int) -> int:
    """ObjectJointRevolute2D: 2 multipliers; the force on marker1's body is -lam, on
    marker0's body +lam (world axes), measured in tests/test_engine_exudyn.py."""
    return model.mbs.AddObject(ObjectJointRevolute2D(markerNumbers=[marker0, marker1]))


def rigid_frame(model, body: int, pos, rot=None) -> int:
    """A rigid-body marker (a frame) at local position ``pos`` of a body (or the ground), its
    axes ``rot`` (body components; default the body's axes): what 3-D joints connect."""
    rot = np.eye(3) if rot is None else np.asarray(rot)
    return model.mbs.AddMarker(
        MarkerBodyRigid(
            bodyNumber=body, localHT=exu.HT(rotation=rot.tolist(), translation=list(pos))
        )
    )


def coordinate_marker(model, node: int, index: int) -> int:
    return model.mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=node, coordinate=index))


def ground_coordinate(model) -> int:
    """A coordinate marker on a ground node (the fixed side of a coordinate constraint)."""
    n = model.mbs.AddNode(NodePointGround(referenceCoordinates=[0.0, 0.0, 0.0]))
    return coordinate_marker(model, n, 0)
