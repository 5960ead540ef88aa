"""Two defects of Pinocchio's computeConstraintDynamicsDerivatives (4.1.0; the same code in
3.7.0), reproduced with Pinocchio alone against central differences of its own
constraintDynamics along the loop's tangent (the positions and the speeds moved together, so
that the loop stays closed): the defects the `derivatives` records find
(docs/engines/pinocchio.md, "Derivatives").

    python benchmarks/pinocchio_loop_derivatives.py

prints, per case, the largest relative difference between the analytical directional
derivative of the accelerations and of the contact forces, and the central one (step 1e-5:
about 1e-9 where they agree).

1. A CONTACT_3D constraint whose second joint is not the world: RigidConstraintModel's
   constructor sizes `loop_span_indexes` to nv zeros and `init` then push_backs the loop's
   columns, so the routine adds the loop-closure term of tangent column 0 nv times too many.
   Wrong wherever column 0 rotates (its Jacobian has an angular part); not the proximal
   regularization of a planar loop's dependent row: a spatial loop with 3 independent rows and
   the exact Cholesky (mu = 0) is as wrong, and mu from 1e-8 to 1e-2 leaves the error as it is.
   The same model with a slider as column 0 is right, and so is the routine's output with the
   nv extra copies taken out (`spurious_column0`). Pinocchio's own unit tests build their loops
   on humanoidRandom with a free flyer, whose column 0 is a translation.
2. The world as the constraint's first joint: the routine writes data.dac_da (the constraint
   Jacobian it differentiates with) only where joint1 is not the world and subtracts joint2's
   part from what is there, and zeros dac_dq and dac_dv but not dac_da, so each call on the
   same Data subtracts it once more. initConstraintDynamics zeros it: re-initializing before
   each call (or a fresh Data) removes the drift, which Pinocchio's own dirty-data unit test
   (repeated calls on one Data) does not see because its constraints have joint2 = world.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

RX, RY, RZ = pin.JointModelRX, pin.JointModelRY, pin.JointModelRZ
PX, PY = pin.JointModelPX, pin.JointModelPY
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
PROX = (1e-12, 1e-8, 50)


def at(x, y=0.0, z=0.0):
    return pin.SE3(np.eye(3), np.array([x, y, z]))


def link(model, joint, length):
    inertia = pin.Inertia(1.0, np.array([length / 2, 0, 0]), np.diag([0.01, 0.02, 0.03]))
    model.appendBodyToJoint(joint, inertia, pin.SE3.Identity())


def gap_and_jacobian(model, data, cms, cds, q):
    """The anchors' gap p1 - p2 and the constraint Jacobian at q (the constraint data
    recomputed first: getConstraintsJacobian reads their placements)."""
    cm, cd = cms[0], cds[0]
    pin.forwardKinematics(model, data, q)
    pin.computeJointJacobians(model, data, q)
    cm.calc(model, data, cd)
    gap = cd.oMc1.translation - cd.oMc2.translation
    return gap, pin.getConstraintsJacobian(model, data, cms, cds).copy()


def closed_state(model, data, cms, cds, rng):
    """A configuration on the loop (Gauss-Newton from a random one, its steps clipped to 0.3
    near a stretched chain), a speed tangent to it."""
    q = pin.neutral(model) + 0.3 * rng.standard_normal(model.nq)
    for _ in range(100):
        gap, J = gap_and_jacobian(model, data, cms, cds, q)
        step = -np.linalg.pinv(J, rcond=1e-9) @ gap
        q = pin.integrate(model, q, step * min(1.0, 0.3 / max(np.linalg.norm(step), 1e-300)))
    gap, J = gap_and_jacobian(model, data, cms, cds, q)
    assert np.linalg.norm(gap) < 1e-12, f"the loop did not close: {gap}"
    v = (np.eye(model.nv) - np.linalg.pinv(J) @ J) @ rng.standard_normal(model.nv)
    return q, v, J


def spurious_column0(model, data, cm, cd):
    """What the routine adds to its dtau_dq (column 0) through the nv zeros in front of
    loop_span_indexes: nv times column 0's loop-closure term, for j in joint2's support
    (J_j's velocity of the point c2) . (f x omega_0), + where column 0 moves joint2, - else
    (LOCAL_WORLD_ALIGNED CONTACT_3D with joint2 > 0; the force is world-aligned)."""
    cols = [
        model.idx_vs[j] + k
        for j in model.supports[cm.joint2_id]
        if j > 0
        for k in range(model.nvs[j])
    ]
    J, f, p2 = np.array(data.J), cd.contact_force.linear, cd.oMc2.translation
    sign = 1.0 if 0 in cols else -1.0
    dD = np.zeros((model.nv, model.nv))
    for j in cols:
        dD[j, 0] = model.nv * sign * (J[:3, j] + np.cross(J[3:, j], p2)) @ np.cross(f, J[3:, 0])
    return dD


def worst_difference(
    model, closure, rng, calls: int = 1, prox=PROX, reinit: bool = False, correct: bool = False
) -> tuple[float, float]:
    """max over the loop's tangent directions of |analytical - central| / max(|central|, 1),
    for the accelerations and the contact forces, the analytical derivatives from the
    routine's `calls`-th call at the state (the same Data each time, as a controller calls it;
    `reinit`: initConstraintDynamics before each call; `correct`: spurious_column0 taken out,
    its effect on the outputs being -ddq_dtau dD and -dlambda_dtau dD)."""
    data = model.createData()
    cms, cds = pin.StdVec_RigidConstraintModel(), pin.StdVec_RigidConstraintData()
    cm = pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, *closure, LWA)
    cms.append(cm)
    cds.append(cm.createData())
    pin.initConstraintDynamics(model, data, cms, cds)
    settings = pin.ProximalSettings(*prox)
    q, v, J = closed_state(model, data, cms, cds, rng)
    tau = rng.standard_normal(model.nv)

    def answer(qq, vv):
        a = pin.constraintDynamics(model, data, qq, vv, tau, cms, cds, settings).copy()
        return a, cds[0].contact_force.linear.copy()

    def jac(qq):
        return gap_and_jacobian(model, data, cms, cds, qq)[1]

    _u, s, vt = np.linalg.svd(J)
    h, worst = 1e-5, [0.0, 0.0]
    for n in vt[int((s > 1e-9 * s[0]).sum()) :]:
        dJv = jac(pin.integrate(model, q, h * n)) @ v - jac(pin.integrate(model, q, -h * n)) @ v
        dv = -np.linalg.pinv(J) @ dJv / (2 * h)
        for _ in range(calls):
            if reinit:
                pin.initConstraintDynamics(model, data, cms, cds)
            answer(q, v)
            out = [
                np.array(x).reshape(-1, model.nv)
                for x in pin.computeConstraintDynamicsDerivatives(model, data, cms, cds, settings)
            ]
        if correct and cm.joint2_id > 0:
            dD = spurious_column0(model, data, cm, cds[0])
            out[0] = out[0] + out[2] @ dD
            out[3] = out[3] + out[5] @ dD
        plus = answer(pin.integrate(model, q, h * n), v + h * dv)
        minus = answer(pin.integrate(model, q, -h * n), v - h * dv)
        for k, (dq_, dv_) in enumerate(((out[0], out[1]), (out[3], out[4]))):
            analytical = dq_ @ n + dv_ @ dv
            central = (plus[k] - minus[k]) / (2 * h)
            err = np.max(np.abs(analytical - central)) / max(1.0, np.max(np.abs(central)))
            worst[k] = max(worst[k], float(err))
    return worst[0], worst[1]


def slider_crank(slider_first: bool = False):
    """A 2R arm whose tip is held on a root slider; `slider_first`: the slider's column is 0."""
    m = pin.Model()
    if slider_first:
        s = m.addJoint(0, PX(), pin.SE3.Identity(), "s")
        link(m, s, 0.0)
    a = m.addJoint(0, RZ(), pin.SE3.Identity(), "a")
    link(m, a, 1.0)
    b = m.addJoint(a, RZ(), at(1.0), "b")
    link(m, b, 0.8)
    if not slider_first:
        s = m.addJoint(0, PX(), pin.SE3.Identity(), "s")
        link(m, s, 0.0)
    return m, (b, at(0.8), s, pin.SE3.Identity())


def cases():
    """(name, model, closure, options): chains closed by one 3-D point constraint."""
    m = pin.Model()
    a = m.addJoint(0, RZ(), pin.SE3.Identity(), "a")
    link(m, a, 1.0)
    b = m.addJoint(a, RZ(), at(1.0), "b")
    link(m, b, 0.8)
    c = m.addJoint(b, RZ(), at(0.8), "c")
    link(m, c, 0.5)
    first = (0, at(1.2, 0.5), c, at(0.5))
    yield "3R arm tip to a world point", m, (c, at(0.5), 0, at(1.2, 0.5)), {}
    yield "the same, the world first (3rd call)", m, first, {"calls": 3}
    yield "  ... initConstraintDynamics before each call", m, first, {"calls": 3, "reinit": True}
    yield (
        "  ... and column 0's extra copies taken out",
        m,
        first,
        {"calls": 3, "reinit": True, "correct": True},
    )
    m, closure = slider_crank()
    yield "2R arm tip to a root slider (slider_crank)", m, closure, {}
    for mu in (1e-4, 1e-2):
        yield f"  ... proximal mu {mu:.0e}", m, closure, {"prox": (1e-12, mu, 200)}
    yield "  ... column 0's nv extra copies taken out", m, closure, {"correct": True}
    m, closure = slider_crank(slider_first=True)
    yield "  ... the slider first (column 0 a translation)", m, closure, {}
    m = pin.Model()
    a = m.addJoint(0, RZ(), pin.SE3.Identity(), "a")
    link(m, a, 1.0)
    b = m.addJoint(a, RZ(), at(1.0), "b")
    link(m, b, 2.0)
    c = m.addJoint(0, RZ(), at(2.0), "c")
    link(m, c, 1.5)
    yield "four-bar: coupler tip to rocker tip", m, (b, at(2.0), c, at(1.5)), {}
    m = pin.Model()
    a = m.addJoint(0, RZ(), pin.SE3.Identity(), "a")
    link(m, a, 1.0)
    s = m.addJoint(0, PX(), pin.SE3.Identity(), "s")
    link(m, s, 0.0)
    r = m.addJoint(s, RZ(), pin.SE3.Identity(), "r")
    link(m, r, 2.0)
    yield "crank tip to a rod on a slider (slider_crank_split)", m, (a, at(1.0), r, at(2.0)), {}
    m = pin.Model()
    x = m.addJoint(0, PX(), pin.SE3.Identity(), "x")
    bar = m.addJoint(x, RZ(), pin.SE3.Identity(), "bar")
    link(m, bar, 1.0)
    y = m.addJoint(0, PY(), pin.SE3.Identity(), "y")
    link(m, y, 0.0)
    yield "bar on a slider to a root slider (exercise_6_1)", m, (bar, at(1.0), y, at(0.0)), {}
    m = pin.Model()
    a = m.addJoint(0, RX(), pin.SE3.Identity(), "a")
    link(m, a, 1.0)
    b = m.addJoint(a, RY(), at(1.0), "b")
    link(m, b, 1.0)
    c = m.addJoint(b, RZ(), at(1.0), "c")
    link(m, c, 1.0)
    d = m.addJoint(0, RY(), at(1.5, 0.5), "d")
    link(m, d, 1.0)
    spatial = (c, at(0.7), d, at(0.6))
    yield (
        "spatial RX-RY-RZ arm to an RY rocker (3 rows, mu 0)",
        m,
        spatial,
        {"prox": (1e-12, 0.0, 1)},
    )
    yield (
        "  ... column 0's nv extra copies taken out",
        m,
        spatial,
        {
            "prox": (1e-12, 0.0, 1),
            "correct": True,
        },
    )


def measured() -> dict[str, tuple[float, float]]:
    """Each case's worst relative difference (accelerations, contact forces)."""
    out = {}
    for name, model, closure, options in cases():
        model.gravity = pin.Motion(np.array([0, -9.81, 0, 0, 0, 0]))
        out[name] = worst_difference(model, closure, np.random.default_rng(0), **options)
    return out


if __name__ == "__main__":
    print(f"pinocchio {pin.__version__}{'':36s} accelerations  forces")
    for name, (acc, force) in measured().items():
        print(f"{name:55s} {acc:.1e}        {force:.1e}")
