"""Pinocchio's computeConstraintDynamicsDerivatives on planar loops closed by a 3-D point
constraint, against central differences of its own constraintDynamics along the loop's
tangent (the positions and the speeds moved together, so that the loop stays closed): the
defect the `derivatives` records find on the slider-cranks (docs/engines/pinocchio.md),
reproduced with Pinocchio alone.

    python benchmarks/pinocchio_loop_derivatives.py

prints, per case, the largest relative difference between the analytical directional
derivative of the accelerations and the central one (step 1e-5: about 1e-9 where they agree).
One case repeats the routine at the state: with the world as the constraint's first joint its
derivatives are right on the first call and drift on every later one on the same Data (the
users' files whose `connect` names the world's body first).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

RZ, PX, PY = pin.JointModelRZ, pin.JointModelPX, pin.JointModelPY
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
PROX = (1e-12, 1e-8, 50)


def at(x, y=0.0):
    return pin.SE3(np.eye(3), np.array([x, y, 0.0]))


def link(model, joint, length):
    inertia = pin.Inertia(1.0, np.array([length / 2, 0, 0]), np.diag([0.01, 0.02, 0.03]))
    model.appendBodyToJoint(joint, inertia, pin.SE3.Identity())


def closed_state(model, data, cms, cds, rng):
    """A configuration on the loop (Gauss-Newton from a random one), a speed tangent to it."""
    cm = cms[0]
    q = pin.neutral(model) + 0.3 * rng.standard_normal(model.nq)
    for _ in range(50):
        pin.forwardKinematics(model, data, q)
        p1 = (data.oMi[cm.joint1_id] * cm.joint1_placement).translation
        p2 = (data.oMi[cm.joint2_id] * cm.joint2_placement).translation
        pin.computeJointJacobians(model, data, q)
        J = pin.getConstraintsJacobian(model, data, cms, cds)
        q = pin.integrate(model, q, -np.linalg.pinv(J) @ (p1 - p2))
    pin.computeJointJacobians(model, data, q)
    J = pin.getConstraintsJacobian(model, data, cms, cds)
    v = (np.eye(model.nv) - np.linalg.pinv(J) @ J) @ rng.standard_normal(model.nv)
    return q, v, J


def worst_difference(model, closure, rng, calls: int = 1) -> float:
    """max over the loop's tangent directions of |analytical - central| / max(|central|, 1),
    the analytical derivatives from the routine's `calls`-th call at the state (the same
    Data each time, as a controller calls it)."""
    data = model.createData()
    cms, cds = pin.StdVec_RigidConstraintModel(), pin.StdVec_RigidConstraintData()
    cm = pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, *closure, LWA)
    cms.append(cm)
    cds.append(cm.createData())
    pin.initConstraintDynamics(model, data, cms, cds)
    prox = pin.ProximalSettings(*PROX)
    q, v, J = closed_state(model, data, cms, cds, rng)
    tau = rng.standard_normal(model.nv)

    def acc(qq, vv):
        return pin.constraintDynamics(model, data, qq, vv, tau, cms, cds, prox).copy()

    def jac(qq):
        pin.computeJointJacobians(model, data, qq)
        return pin.getConstraintsJacobian(model, data, cms, cds).copy()

    _u, s, vt = np.linalg.svd(J)
    h, worst = 1e-5, 0.0
    for n in vt[int((s > 1e-9 * s[0]).sum()) :]:
        dJv = jac(pin.integrate(model, q, h * n)) @ v - jac(pin.integrate(model, q, -h * n)) @ v
        dv = -np.linalg.pinv(J) @ dJv / (2 * h)
        for _ in range(calls):
            acc(q, v)
            out = pin.computeConstraintDynamicsDerivatives(model, data, cms, cds, prox)
        dq_, dv_ = (np.array(x) for x in out[:2])
        analytical = dq_ @ n + dv_ @ dv
        plus = acc(pin.integrate(model, q, h * n), v + h * dv)
        minus = acc(pin.integrate(model, q, -h * n), v - h * dv)
        central = (plus - minus) / (2 * h)
        err = np.max(np.abs(analytical - central)) / max(1.0, np.max(np.abs(central)))
        worst = max(worst, float(err))
    return worst


def cases():
    """(name, model, closure): planar chains, each closed by one 3-D point constraint."""
    m = pin.Model()
    a = m.addJoint(0, RZ(), pin.SE3.Identity(), "a")
    link(m, a, 1.0)
    b = m.addJoint(a, RZ(), at(1.0), "b")
    link(m, b, 0.8)
    yield "2R arm tip to a world point", m, (b, at(0.8), 0, at(1.2, 0.5))
    yield "the same, the world first (3rd call)", m, (0, at(1.2, 0.5), b, at(0.8))
    m = pin.Model()
    a = m.addJoint(0, RZ(), pin.SE3.Identity(), "a")
    link(m, a, 1.0)
    b = m.addJoint(a, RZ(), at(1.0), "b")
    link(m, b, 0.8)
    s = m.addJoint(0, PX(), pin.SE3.Identity(), "s")
    link(m, s, 0.0)
    yield "2R arm tip to a root slider (slider_crank)", m, (b, at(0.8), s, pin.SE3.Identity())
    m = pin.Model()
    a = m.addJoint(0, RZ(), pin.SE3.Identity(), "a")
    link(m, a, 1.0)
    b = m.addJoint(a, RZ(), at(1.0), "b")
    link(m, b, 2.0)
    c = m.addJoint(0, RZ(), at(2.0), "c")
    link(m, c, 1.5)
    yield "four-bar: coupler tip to rocker tip", m, (b, at(2.0), c, at(1.5))
    m = pin.Model()
    a = m.addJoint(0, RZ(), pin.SE3.Identity(), "a")
    link(m, a, 1.0)
    s = m.addJoint(0, PX(), pin.SE3.Identity(), "s")
    link(m, s, 0.0)
    r = m.addJoint(s, RZ(), pin.SE3.Identity(), "r")
    link(m, r, 2.0)
    yield "crank tip to a rod on a slider (slider_crank_split)", m, (a, at(1.0), r, at(2.0))
    m = pin.Model()
    x = m.addJoint(0, PX(), pin.SE3.Identity(), "x")
    bar = m.addJoint(x, RZ(), pin.SE3.Identity(), "bar")
    link(m, bar, 1.0)
    y = m.addJoint(0, PY(), pin.SE3.Identity(), "y")
    link(m, y, 0.0)
    yield "bar on a slider to a root slider (exercise_6_1)", m, (bar, at(1.0), y, at(0.0))


if __name__ == "__main__":
    print(f"pinocchio {pin.__version__}")
    for name, model, closure in cases():
        model.gravity = pin.Motion(np.array([0, -9.81, 0, 0, 0, 0]))
        calls = 3 if "3rd call" in name else 1
        err = worst_difference(model, closure, np.random.default_rng(0), calls)
        print(f"{name:55s} {err:.1e}")
