"""The benchmarks of `crosscheck bench`: forward-dynamics speed against the engines, work-precision,
stress scenes, the compiled stepper, and the ratios each figure is judged by."""
