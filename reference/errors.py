"""Errors that name the problem and the way out.

Every error the suite raises on bad input is a `ModelInputError` subclass, so the CLI can print
one clear line and exit with status 2 instead of a traceback.
"""


class ModelInputError(ValueError):
    """Bad input to a model: unknown name, missing parameter, wrong state size, NaN, ..."""


class ModelDefinitionError(ModelInputError):
    """A model declaration is inconsistent (collected and raised once, at construction)."""

    def __init__(self, model: str, problems: list[str]):
        self.model = model
        self.problems = list(problems)
        super().__init__(f"model {model!r} is inconsistent: " + "; ".join(problems))


class RedundantConstraintError(ModelInputError):
    """The constraint rows are linearly dependent (rank(A) < m, Eq. 4 discussion)."""


class SingularSystemError(ModelInputError):
    """The KKT matrix is singular at a state (kinematic singularity, M not definite on
    null(A), or a coordinate singularity where the derived equations are not defined)."""

    t_singular: float | None = None  # set by an integrator: the time the run reached the pose


class OffManifoldError(ModelInputError):
    """A state violates the constraints by more than the stated tolerance."""


class InconsistentConstraintError(ModelInputError):
    """Dependent constraint rows that contradict each other: no motion satisfies all of them."""


class UnsupportedModelError(ModelInputError):
    """A model file holds an element the reference cannot represent (named, with the way out)."""


class ModelFileError(ModelInputError):
    """A model file cannot be read: malformed, rejected by its compiler, or defines no models."""
