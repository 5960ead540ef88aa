"""Numeric evaluation of a model's equations of motion: NumericModel (model) with its one checked
forward (`forward`) and one fast forward (`forward_fast`), batched forward dynamics (batch), the
checks and error messages (validate), the constraint manifold (manifold) and the KKT solve with
dependent rows (redundant). The kernels beneath are reference.backends'."""
