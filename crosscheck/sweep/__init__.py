"""Seeded random campaigns of the instantaneous checks: settings (config), one chunk (worker),
where chunks run (executors), finished chunks on disk (store), the plan (campaign), the
summary (aggregate) and the throughput benchmark (bench)."""
