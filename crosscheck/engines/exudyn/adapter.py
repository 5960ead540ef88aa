"""Exudyn 1.13 adapter: the reference models built as Exudyn multibody systems (redundant
coordinates, Lagrange multipliers), answered by Exudyn's implicit solver.

How one state is answered, and why the answer is Richardson-extrapolated over Exudyn's
finite-difference step, is in base.py; the state and multiplier maps of every model are in
its class docstring (planar.py, special.py, spatial.py, exercises.py); docs/engines/exudyn.md
has the measured agreement and the commands that measure it.
"""

from __future__ import annotations

from collections.abc import Callable

from crosscheck.checks.tolerances import Tolerance
from crosscheck.engines.base import Capabilities
from crosscheck.engines.building import TableAdapter, is_user_model, single_variant
from crosscheck.engines.exudyn.engine_model import INTEGRATORS, ExudynModel
from crosscheck.engines.exudyn.exercises import Exercise61, Exercise62, Exercise64
from crosscheck.engines.exudyn.planar import (
    PendulumAngle,
    PendulumXY,
    SliderCrank,
    SliderCrankFree,
    SliderCrankSplit,
)
from crosscheck.engines.exudyn.spatial import DoublePendulum3D, FrameBar, TopCartesian, TopEuler
from crosscheck.engines.exudyn.special import KnifeEdge, MovingSupport

__all__ = ["EXUDYN_EXACT", "EXUDYN_USER_FILES", "ExudynAdapter"]

_MODELS: dict[str, Callable[[str, dict[str, float]], ExudynModel]] = {
    "pendulum_angle": PendulumAngle,
    "pendulum_xy": PendulumXY,
    "slider_crank_free": SliderCrankFree,
    "slider_crank": SliderCrank,
    "slider_crank_split": SliderCrankSplit,
    "knife_edge": KnifeEdge,
    "pendulum_moving_support": MovingSupport,
    "double_pendulum_3d": DoublePendulum3D,
    "top_cartesian": TopCartesian,
    "top_euler": TopEuler,
    "exercise_6_1": Exercise61,
    "exercise_6_2": Exercise62,
    "exercise_6_4": Exercise64,
    "frame_bar": FrameBar,
}

# Reference models without an Exudyn model here, each with the reason shown in results:
# none (every built-in model is built; docs/engines/exudyn.md).
_UNSUPPORTED: dict[str, str] = {}

EXUDYN_EXACT = Tolerance(
    1e-9,
    "Exudyn's answer Richardson-extrapolated over its finite-difference step (three "
    "InitializeSolver calls, relativeEpsilon 3e-4, 1.5e-4, 7.5e-5, minimumCoordinateSize "
    "1; engine_model.py): measured worst 1.4e-10 scaled error over 100 sampled states per "
    "model on all 14 models (pendulum_moving_support's multiplier; accelerations <= 3.1e-11), "
    "against 2.4e-8..9.8e-7 for Exudyn's plain answer at its default relativeEpsilon "
    "1e-7 (PYTHONPATH=$PWD python -m crosscheck.engines.exudyn.measure --samples 100); "
    "1e-9 is the suite's bound for a numerical engine answer, 7x above the worst figure, "
    "~100x below the effect of a "
    "1e-6 parameter fault",
)


EXUDYN_USER_FILES = Tolerance(
    1e-9,
    "Exudyn's answer on its model of the file (built from MuJoCo's compiled model), "
    "Richardson-extrapolated over its finite-difference step as for the built-in models; "
    "measured worst 2.7e-11 (accelerations) and 1.1e-11 (multipliers) over 6 states of 33 "
    "files: the test files, IFToMM A01 and A02, 23 of MuJoCo's test models "
    "(docs/engines/exudyn.md, \"Users' MJCF files\"); 1e-9 is the suite's bound for a "
    "numerical engine answer, 37x above the worst figure",
)


class ExudynAdapter(TableAdapter):
    """EngineAdapter for Exudyn 1.13 (see the module docstring)."""

    name = "exudyn"
    distribution = "exudyn"
    capabilities = Capabilities(
        multipliers=True, exact=True, nonholonomic=True, integrators=tuple(INTEGRATORS)
    )
    model_table = _MODELS
    refused = _UNSUPPORTED
    user_files = True  # users' MJCF files, built from MuJoCo's compiled model (user_file.py)

    def exact_tolerance(self, model_name: str) -> Tolerance:
        """EXUDYN_EXACT, and on a user's file EXUDYN_USER_FILES (the same bound, measured
        there)."""
        return EXUDYN_USER_FILES if is_user_model(_MODELS, model_name) else EXUDYN_EXACT

    def build(
        self, model_name: str, params: dict[str, float] | None = None, variant: str | None = None
    ):
        if is_user_model(_MODELS, model_name):
            from crosscheck.engines.exudyn.user_file import ExudynUserFile

            single_variant(self.name, model_name, variant, "a user's file")
            return ExudynUserFile(model_name, params)
        return super().build(model_name, params, variant)
