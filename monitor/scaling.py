"""Nominal magnitudes the identifier's RLS rows are scaled by, so every parameter is O(1) (SI).

Kept apart from ``monitor.identify`` so the read-out (``monitor.estimates``) and the per-sample
kernel can share them without importing each other.
"""

import numpy as np

# m [kg], B+f_v [N s/m], f_c [N], K_t [N/m], F_0 [N] (a constant force: sensor zeros, preload)
THETA_NOM_F = np.array([100.0, 1e4, 10.0, 1e6, 1e3])
Y_NOM_F = 1e4  # [N]
THETA_NOM_C = np.array([1e-9, 1e-3, 1e-11, 1e-11])  # 1/beta [1/Pa], theta, C_ip, C_ep
Y_NOM_C = 1e-3  # [m^3/s]
X5_NOM = 1e-4  # [m]
THETA_NOM_K = np.array([2.5e-4, 1e-2, 1e-4])  # K_sv [m/V], 2 zeta / omega [s], 1 / omega^2 [s^2]
