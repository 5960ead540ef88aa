"""Time integration with constraint stabilization: the driver and its method registry (driver),
the method families (index1, projection, nullspace) over a shared base (common), the DOP853
step (rk) and the whole run in compiled code (compiled)."""

# the constraint treatments simulate() takes; here, apart from the solvers, so that a command
# line can list them without importing scipy.integrate
METHODS = ("index1", "baumgarte", "projection", "nullspace")
