import os

os.environ.setdefault("MPLBACKEND", "Agg")

from hydromon.tools import jitcache  # noqa: E402

jitcache.configure()  # before any test module imports a kernel
