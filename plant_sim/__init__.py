from plant_sim import _jitcache  # noqa: F401  (before any kernel is compiled)
