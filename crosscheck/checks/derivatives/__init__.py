"""The derivatives check: the exact derivatives of the reference's forward answer
(reference.derivatives) against each engine's, analytical or differenced, block by block
(engine), with tolerances derived from what limits each comparison (tolerances), planted
faults (faults) and the records (records)."""
