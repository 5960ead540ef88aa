"""Exudyn 1.13 adapter: the reference models built as Exudyn multibody systems (redundant
coordinates, Lagrange multipliers), answered by Exudyn's implicit solver.

How one state is answered, and why the answer is Richardson-extrapolated over Exudyn's
finite-difference step, is in base.py; the state and multiplier maps of every model are in its
class docstring (planar.py, special.py, spatial.py); docs/engines/exudyn.md has the measured
agreement and the commands that measure it.
"""
from __future__ import annotations

from typing import Optional

from ...compare import Tolerance
from ..base import Capabilities, EngineAdapter, EngineUnsupported
from .base import INTEGRATORS
from .special import KnifeEdge, MovingSupport
from .planar import PendulumAngle, PendulumXY, SliderCrank, SliderCrankFree, SliderCrankSplit

__all__ = ["ExudynAdapter", "EXUDYN_EXACT"]

_MODELS = {
    "pendulum_angle": PendulumAngle,
    "pendulum_xy": PendulumXY,
    "slider_crank_free": SliderCrankFree,
    "slider_crank": SliderCrank,
    "slider_crank_split": SliderCrankSplit,
    "knife_edge": KnifeEdge,
    "pendulum_moving_support": MovingSupport,
}

_UNSUPPORTED: dict[str, str] = {}

EXUDYN_EXACT = Tolerance(
    1e-9, "Exudyn's answer Richardson-extrapolated over its finite-difference step (three "
          "InitializeSolver calls, relativeEpsilon 1e-3, 5e-4, 2.5e-4); placeholder until "
          "measured")


def _resolve(model_name: str, params: Optional[dict]) -> dict[str, float]:
    from reference.models import get
    from reference.numeric import resolve_parameters

    return resolve_parameters(get(model_name), params)


class ExudynAdapter(EngineAdapter):
    """EngineAdapter for Exudyn 1.13 (see the module docstring)."""

    name = "exudyn"
    distribution = "exudyn"
    capabilities = Capabilities(multipliers=True, exact=True, nonholonomic=True,
                                integrators=tuple(INTEGRATORS))

    def models(self) -> tuple[str, ...]:
        return tuple(_MODELS)

    def unsupported(self) -> dict[str, str]:
        return dict(_UNSUPPORTED)

    def build(self, model_name: str, params: Optional[dict[str, float]] = None,
              variant: Optional[str] = None):
        if model_name in _UNSUPPORTED:
            raise EngineUnsupported(_UNSUPPORTED[model_name])
        if model_name not in _MODELS:
            raise EngineUnsupported(
                f"exudyn adapter has no model {model_name!r} (mapped: {', '.join(_MODELS)})")
        if variant is not None:
            raise EngineUnsupported(f"{model_name}: exudyn has a single variant here")
        return _MODELS[model_name](model_name, _resolve(model_name, params))

    def exact_tolerance(self, model_name: str) -> Tolerance:
        return EXUDYN_EXACT
