"""Pinocchio 4.1 adapter: the reference models built in code, solved by Pinocchio's own algorithms.

Why in code and not from the MJCF the MuJoCo adapter uses: checked file by file in
tests/test_pinocchio_mjcf.py (pin 4.1.0). With gravity set by hand (the parser ignores
``<option gravity>``: always (0, 0, -9.81)) and the springs and dampers passed as tau (joint
stiffness is not parsed; damping lands in model.damping, which aba does not apply), the parser
is right on every tree file (pendulum_angle, slider_crank_free, double_pendulum_3d_tree,
frame_bar, top_euler, exercise_6_2, exercise_6_4: aba equals MuJoCo on the same file to 1e-12
and this module's models to the files' 1e-12 light bodies) and, through
``buildModelAndLegacyConstraintsFromMJCF`` (CONTACT_3D in the LOCAL frame) and
constraintDynamics, on slider_crank, slider_crank_split, exercise_6_1 and top_cartesian
(accelerations and forces as here). It is wrong where it matters elsewhere: with two free
bodies (double_pendulum_3d_free) it parses only the first top-level body and rebinds the
connects silently (sorted by name, the missing body and a world site becoming the universe
with an uninitialized placement); a site-based connect to a world site crashes it (SIGSEGV);
and pendulum_xy's light rod, which the file needs because MuJoCo's tendon equality lacks
J-dot v, parses right but makes the Delassus matrix so ill-conditioned (1e12) that
constraintDynamics is 1e-4 off. The models stay built in code, with the textbook rows where a
file has a workaround, so nothing depends on patching a parse; the tests keep the parser
honest and fail when an upgrade changes any of the above.

Engine frames and coordinates (the maps are written out in each class's docstring):
- Planar models use the engine world with X right, Y UP, gravity (0, -g, 0), hinges about +Z.
  Models written with Y DOWN in the reference (Example 1, the moving support, Exercise 6.2) get
  y_ref = -y_engine in their maps; Example 2, Note 2 / Exercise 6.3 and Exercise 6.1 are Y up in
  both. The 3-D models use the reference's own axes (N2 up for Example 4, N3 / Z up for the
  tops and Exercise 6.4), gravity set by hand (``model.gravity``).
- Bodies that are planar bars in the reference carry only I_zz. In the engine each gets the full
  inertia of a planar lamina, diag(I_zz/2, I_zz/2, I_zz) (perpendicular-axis theorem, a valid
  rigid-body inertia). Hinges about Z and slides in X/Y never excite the in-plane components, so
  they do not change any planar answer (tests/test_engine_pinocchio.py checks this by changing
  them). 3-D bodies get exactly the reference's inertias.
- Point masses (the pendulum bob, the slider, the blocks) get NO rotational inertia: each one
  either translates on prismatic joints (the joint-space inertia is its mass) or sits off the
  axis of the hinge that carries it (m L^2 > 0), so Pinocchio never needs one and the engine
  model has exactly the reference's mass distribution. Exercise 6.4's bar keeps its zero axial
  inertia too (the disk's inertia keeps the mass matrix definite).
- Loads: constant torques/forces go to tau; springs, dampers and loads that turn with a body are
  evaluated per state (``_applied``), and the springs' potential is added to V. Only the moving
  support is rheonomic: its explicit time terms enter the constraint row; t is unused elsewhere.

Solvers (docs/engines/pinocchio.md, re-verified in the tests):
- no constraints, or a minimal-coordinate tree (joint reactions from rnea): ``pin.aba``;
- rows that are not point coincidences (x^2 + y^2 = L^2, the rheonomic moving support, the
  nonholonomic knife edge): ``pin.forwardDynamics(model, data, q, v, tau, J, gamma)`` with the
  textbook row J and gamma = Jdot v + (explicit time terms), an exact KKT solve whose
  data.lambda_c has the textbook sign: M a + nle = tau + J^T lambda, J a + gamma = 0;
- point coincidences (loop closures, free bodies held at points): ``RigidConstraintModel``
  CONTACT_3D in LOCAL_WORLD_ALIGNED with ``pin.constraintDynamics``. A planar loop gives 3 rows
  of which the out-of-plane one is identically zero, so the Delassus matrix is singular and the
  plain Cholesky (mu = 0) returns NaN; ProximalSettings(1e-12, 1e-8, 50) (PROX_REDUNDANT)
  converges to the exact minimum-norm answer in 3 proximal iterations. Full-rank 3-D rows use
  the exact one-step Cholesky (PROX_EXACT). contact_force is the force that joint2's body
  applies to joint1's body at the anchor, world-oriented.
  Pinocchio's own ``prox.absolute_residual`` is NOT a KKT residual (it stays O(10) even when the
  answer is exact to 1e-15) and ``relative_residual`` after one iteration is |lambda|_inf, so
  forward() reports independent residuals: primal |J a + gamma|_inf (anchor classical
  accelerations) and dual |rnea(q, v, a, f_ext) - tau|_inf (Pinocchio's inverse dynamics with
  the constraint forces applied).

Engine variants: Example 4 and Exercise 6.7 have two engine models each ("free": free bodies
held by point constraints, the textbook's own form; "tree": ball joints, joint reactions from
rnea). ``PinocchioAdapter.variants(name)`` lists them, the first is build's default, and
``build(name, params, variant=...)`` selects one (forward's raw["variant"] says which).

Every EngineModel here also has ``mass_matrix(q)`` and ``forcing(q, u, t)`` (the reference's M
and f where the coordinates map linearly, else None), ``constraint_violation`` /
``velocity_violation`` (engine-side drift measures), ``simulate(...)`` (scipy's solve_ivp on
Pinocchio's forward dynamics in the ENGINE's coordinates) and ``timed_forward(q, u)``, the hook
``crosscheck bench`` times (the state mapped once; the callable makes only forward()'s native
Pinocchio call, shared with forward through ``_engine_call``).
"""

from __future__ import annotations

from crosscheck.engines.base import Capabilities
from crosscheck.engines.building import (
    TableAdapter,
    is_user_model,
    lookup_builder,
    resolve_params,
    single_variant,
)
from crosscheck.engines.pinocchio.engine_model import INTEGRATORS, PROX_EXACT, PROX_REDUNDANT
from crosscheck.engines.pinocchio.exercises import Exercise61, Exercise62, Exercise64
from crosscheck.engines.pinocchio.planar import (
    FrameBar,
    KnifeEdge,
    MovingSupport,
    PendulumAngle,
    PendulumXY,
    SliderCrank,
    SliderCrankFree,
    SliderCrankSplit,
)
from crosscheck.engines.pinocchio.spatial import (
    DoublePendulumFree,
    DoublePendulumTree,
    TopCartesianFree,
    TopCartesianTree,
    TopEuler,
)

__all__ = ["INTEGRATORS", "PROX_EXACT", "PROX_REDUNDANT", "PinocchioAdapter"]


# ======================================================================================
# Registry


# ======================================================================================
_MODELS = {
    "pendulum_angle": PendulumAngle,
    "pendulum_xy": PendulumXY,
    "slider_crank": SliderCrank,
    "slider_crank_split": SliderCrankSplit,
    "slider_crank_free": SliderCrankFree,
    "frame_bar": FrameBar,
    # several engine models of one reference model: {variant: class}, the first is the default
    "double_pendulum_3d": {"free": DoublePendulumFree, "tree": DoublePendulumTree},
    "top_euler": TopEuler,
    "top_cartesian": {"free": TopCartesianFree, "tree": TopCartesianTree},
    "knife_edge": KnifeEdge,
    "pendulum_moving_support": MovingSupport,
    "exercise_6_1": Exercise61,
    "exercise_6_2": Exercise62,
    "exercise_6_4": Exercise64,
}

# models of the unit this engine cannot represent, with the reason shown in results
_UNSUPPORTED: dict[str, str] = {}


class PinocchioAdapter(TableAdapter):
    """EngineAdapter for Pinocchio 4.1 (models built in code; see the module docstring)."""

    name = "pinocchio"
    distribution = "pin"
    label = "Pinocchio"
    rank = 10
    capabilities = Capabilities(
        multipliers=True,
        exact=True,
        mass_matrix=True,
        nonholonomic=True,
        integrators=INTEGRATORS,
        variants=True,
        adaptive_integrators=INTEGRATORS,
        reference_integrators=INTEGRATORS,  # machinery.ivp_method: the reference's LeanDOP853
        derivatives="analytic",  # computeConstraintDynamicsDerivatives, computeABADerivatives
    )

    model_table = _MODELS
    refused = _UNSUPPORTED
    user_files = True

    def annotate_records(self, model_name: str, records: list[dict]) -> list[dict]:
        """A user's MJCF file: each record says which Pinocchio model answered, and one more
        record (reported, not judged) lists what pin's own MJCF parser lost."""
        from crosscheck.checks.records import annotated, record
        from crosscheck.engines.pinocchio.parser_findings import findings_isolated, summary
        from crosscheck.engines.pinocchio.user_file import BUILT_FROM
        from reference import models

        src = models.user_source(model_name)
        if not records or not hasattr(src, "mj"):
            return records
        found = findings_isolated(src.path)
        return [
            *(annotated(r, engine_model=BUILT_FROM) for r in records),
            record(
                model_name,
                records[0]["formulation"],
                self.name,
                "parser",
                "mjcf_parse",
                None,
                None,
                summary(found),
                findings=found,
            ),
        ]

    def build(
        self, model_name: str, params: dict[str, float] | None = None, variant: str | None = None
    ):
        if is_user_model(_MODELS, model_name):
            from crosscheck.engines.pinocchio.user_file import UserFilePinModel

            single_variant(self.name, model_name, variant, "a user's file")
            return UserFilePinModel(model_name, params)
        builder = lookup_builder(self.name, _MODELS, model_name, variant, _UNSUPPORTED)
        return builder(model_name, resolve_params(model_name, params))
