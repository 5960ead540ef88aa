"""From equations of motion to fast numeric code: straight-line Python generated and cached on
disk (codegen), the interface every backend's kernels implement (kernels), the generated Python
behind it (python_kernels), the same code printed as C and built (c_source, c_build), and the
choice between them (select)."""
