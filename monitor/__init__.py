"""The numerical core: filters, identification, grading, calibration, audit (pure, deterministic)."""
