"""Per-sample wall time of one pressure observer (observer.ekf, numba) on a 200 s run; order4 on/off.
Usage: python time_obs.py (shared machine: expect +-2x between runs)."""
import numpy as np, time
from variants import *
from observer import ekf
from monitor.layout import STATE_SIZE
print("STATE_SIZE", STATE_SIZE)
runs = runs_for("realistic", seeds=1, seconds=200.0)
s = runs[0].samples
sig = make_noise("realistic").rms
x1, x3, x4, x5 = (np.ascontiguousarray(s[:, i]) for i in (1, 2, 3, 4))
a = (np.array(CP_TRUE, float), np.array(RC, float), cfg.h, np.asarray(sig, float), np.array([30.0]))
for o4 in (True, False):
    ekf(x1, x3, x4, x5, *a, o4)
    t = time.perf_counter()
    for _ in range(5): ekf(x1, x3, x4, x5, *a, o4)
    dt = (time.perf_counter() - t) / 5 / len(x1)
    print("order4", o4, f"{dt*1e9:.0f} ns/sample (incl. writing 5 history arrays)", len(x1))
