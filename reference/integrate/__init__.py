"""Time integration with constraint stabilization: the driver and its method registry (driver),
the method families (index1, projection, nullspace) over a shared base (common), the DOP853
step (rk) and the whole run in compiled code (compiled)."""
