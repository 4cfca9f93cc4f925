import plant_sim  # noqa: F401  (sets the jit cache directory before any kernel is compiled)
