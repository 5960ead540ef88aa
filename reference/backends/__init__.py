"""From equations of motion to fast numeric code: straight-line Python generated and cached on
disk (codegen), printed as C and built (c_source, c_build), or compiled by numba
(numba_backend)."""
