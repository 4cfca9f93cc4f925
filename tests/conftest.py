import os

os.environ.setdefault("MPLBACKEND", "Agg")

from hydromon.cli import jitcache  # noqa: E402

jitcache.configure()  # before any test module imports a kernel
