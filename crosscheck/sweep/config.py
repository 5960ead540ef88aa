"""A sweep campaign's settings: the named constants, each with its reason, and the Campaign
(what to sample, and its validation before any work)."""

from __future__ import annotations

from dataclasses import dataclass, field

from crosscheck.checks.perturb import check_parameters, check_perturb
from crosscheck.commands.arguments import MAX_SAMPLES
from crosscheck.engines.registry import available_engines
from reference import models
from reference.errors import ModelInputError

# ---- named settings, each with its reason ---------------------------------------------------
QUANTILES = (0.5, 0.9, 0.99, 0.999)
QUANTILE_METHOD = "higher"  # each quantile is an observed error (conservative), not interpolated
WORST_CASES = 5  # per model x engine x variant x quantity; --worst changes it
FAULTS_KEPT = 20  # fault records kept per model x engine x variant x stage x type (counts are all)
# A local chunk is at most this many samples: a sample costs 1-6 ms over both engines, so a chunk
# is <= ~1 s, against ~0.2 ms of pool overhead per task, and the batched reference call (a few
# hundred numpy operations, ~1 us each whatever the batch) costs 3-6 us per sample at 200
# against 11-25 us for the scalar path (break-even near 25). Smaller campaigns get smaller chunks
# (N / 4 workers) so the workers stay balanced; an interrupt loses at most one chunk per worker.
LOCAL_CHUNK_MAX = 200
# A Dask task costs ~1-3 ms of scheduling and (de)serialization; 100 samples (0.1-0.6 s) keep that
# below ~1-3% -- unless that would leave workers idle (then N / threads, rounded up).
DASK_MIN_CHUNK = 100
DASK_MAX_CHUNK = 2000
# The parent keeps every error value of a campaign (8 bytes per sample per quantity, ~20
# quantities per model) to give exact quantiles: 10^7 samples of one model hold ~1.6 GB. More is
# refused before any work (run several campaigns with --index instead): MAX_SAMPLES, which the
# command line's --samples, --chunk and --worst share (crosscheck.commands.arguments).
# log10 histogram of each quantity's errors (report figures): 0.25-decade bins from 1e-18 to 1e2;
# exact zeros, values below/above the range and non-finite values are counted apart
HIST_LO, HIST_HI, HIST_STEP = -18.0, 2.0, 0.25

QUANTITY_ORDER = (
    "accelerations",
    "multipliers",
    "accelerations_soft_vs_predicted",
    "multipliers_soft_vs_predicted",
    "accelerations_soft_error",
    "multipliers_soft_error",
    "state_map",
    "mass_matrix",
    "energy",
    # --derivatives: error over the tolerance derived at the sample
    *(f"d{of}_{b}" for b in ("dq", "du", "dtau") for of in ("accelerations", "multipliers")),
    *(f"dconstraint_forces_{b}" for b in ("dq", "du", "dtau")),
    *(
        f"d{of}_{b}_soft_vs_predicted"
        for b in ("dq", "du")
        for of in ("accelerations", "multipliers", "constraint_forces")
    ),
)
SOFT_ERROR_REASON = (
    "MuJoCo's raw (soft) answer against the rigid reference: the error its impedance "
    "d = 0.9999 makes by design (~1e-4 relative); reported, not judged here -- the "
    "*_soft_vs_predicted quantity holds it to the answer predicted from the reference's "
    "and the documented impedance"
)
REFERENCE = "reference"


@dataclass
class Campaign:
    models: list
    samples: int
    seed: int = 0
    index: int = 0
    engines: tuple = field(default_factory=available_engines)
    perturb: dict = field(default_factory=dict)
    formulation: str | None = None
    worst: int = WORST_CASES
    out: str | None = None
    # the derivatives comparison per sample (crosscheck.checks.derivatives)
    derivatives: bool = False

    def validate(self) -> None:
        from crosscheck.commands.arguments import resolve_engines, resolve_models

        if not self.models:
            raise ModelInputError("no models given")
        resolve_models(list(self.models))  # unknown or repeated names fail before any work
        resolve_engines(list(self.engines))
        for e in self.perturb:
            if e not in self.engines:
                raise ModelInputError(
                    f"--perturb names engine {e!r}, which is not in "
                    f"--engines {','.join(self.engines)}"
                )
        for name in self.models:
            check_parameters(name, [p.name for p in models.get(name).parameters], self.perturb)
        check_perturb(self.models, self.perturb)  # nan, or a mass made negative: exit 2
        if self.samples < 1:
            raise ModelInputError(f"--samples must be >= 1, got {self.samples}")
        if self.samples * len(self.models) > MAX_SAMPLES:
            raise ModelInputError(
                f"--samples {self.samples} x {len(self.models)} model(s) is more than the "
                f"{MAX_SAMPLES:.0e} samples a campaign keeps in memory (~160 bytes each, for "
                f"exact quantiles); split it into campaigns with --index"
            )
        if self.seed < 0 or self.index < 0:
            raise ModelInputError("--seed and --index must be >= 0")
        if self.worst < 0:
            raise ModelInputError(f"--worst must be >= 0, got {self.worst}")
