"""Numeric evaluation of a model's equations of motion: NumericModel (model), batched forward
dynamics (batch), the constraint manifold (manifold) and the KKT solve with dependent rows
(redundant)."""
