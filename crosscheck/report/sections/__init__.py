"""Report sections drawn from files beside results.json: the agreement matrix, the sensitivity
thresholds and a sweep's summary."""
