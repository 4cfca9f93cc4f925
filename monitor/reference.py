"""The naive baseline of ``hydromon bench``: the identifier written the straightforward way.

One rig, one Python call per sample, numpy on small arrays: every state-variable filter a
matrix product, every RLS/RIV update the textbook ``K = P phi / (lam + phi' P phi)`` with
``np.outer`` (``monitor.textbook``); no numba, no batching, no flat state row. It implements
the same algorithm as ``monitor.identify.identify_step`` (see that module for the equations:
SVF + RLS for the force and chamber equations, ARX + recursive IV for the valve, the online
noise estimate and the residual statistics), so its throughput is an honest "what the
compiled, batched kernel buys" reference; a test pins its estimates to the compiled path's.

Only the per-sample identification is re-written here: ``estimates()`` packs the state into
``monitor.layout``'s row (``monitor.reference_state``) and reads it out with
``monitor.estimates.estimates`` (the read-out runs once per evaluation, not per sample).
"""

from __future__ import annotations

import math

import numpy as np

from hydromon.contract import RigConfig
from monitor.estimates import estimates, observer_refresh
from monitor.force_observer import FREE, IC_NOM, N_OBS_PARAMS, OBS_REFRESH, PSI_NOM, REF_EVERY
from monitor.fourth_difference import D4_VARIANCE_GAIN
from monitor.ident_model import IdentModel
from monitor.ident_options import STEP_GUARD, IdentOptions, Kernels
from monitor.identify import N_PARAMS, REST_EXCITATION, V_MIN
from monitor.layout import N_CH, N_LAGS, N_OBS, N_STREAMS, O_OBS_SOL, OBS_ORDER, OBS_STATE, RING, SG_HALF, SVF_STATE
from monitor.reference_state import pack_state
from monitor.scaling import THETA_NOM_C, THETA_NOM_F, THETA_NOM_K, X5_NOM, Y_NOM_C, Y_NOM_F
from monitor.textbook import orifice_z, riv, rls, svf_init, svf_step

__all__ = ["NaiveIdentifier"]


class NaiveIdentifier:
    """One rig's identifier, sample by sample in numpy: ``update(sample)``; ``estimates()``.

    Parameters
    ----------
    config : RigConfig
        The rig's constants (areas [m^2], volumes [m^3], p_s [Pa], F_L [N], K_p, K_f [V/m]).
    options : IdentOptions
        The identifier's hyperparameters (those of ``monitor.identify``).
    """

    def __init__(self, config: RigConfig | None = None, options: IdentOptions | None = None):
        self.config = config or RigConfig()
        self.options = options or IdentOptions()
        c, o = self.config, self.options
        k = Kernels(o, c.h)
        self._kernels = k
        self.h = c.h
        # filters (monitor.svf, cubic hold): Phi (3,3) and the input weights G (3,4)
        self.f_mats = (k.m_f[:, :3].copy(), k.m_f[:, 3:].copy())
        self.c_mats = (k.m_c[:, :3].copy(), k.m_c[:, 3:].copy())
        self.o_mats = (k.m_o[:, :OBS_ORDER].copy(), k.m_o[:, OBS_ORDER:].copy())
        self.warm = math.ceil(o.warmup / c.h)
        self.guard = math.ceil(o.reversal_guard / c.h)
        self.rest_pause = math.ceil(o.rest_pause / c.h)
        self.obs_step_guard = math.ceil(o.observer_step_guard / c.h)
        self.n = 0
        self.ring = np.zeros((RING, N_CH))
        self.noise = np.zeros(4)
        self.noise_n = 0.0
        self.svf_f = np.zeros((3, SVF_STATE))  # per signal: [x (3), u(k-1), u(k), u(k+1)]
        self.svf_c = np.zeros((10, SVF_STATE))
        self.th_f, self.P_f = np.zeros(5), np.eye(5) * o.p0  # m, B + f_v, f_c, K_t, F_0
        self.th_c, self.P_c = np.zeros(4), np.eye(4) * o.p0
        self.th_v, self.P_v = np.zeros(5), np.eye(5) * o.p0
        self.xh = np.zeros(2)
        self.rows = np.zeros(3)
        self.slow = 0.0
        self.rest = 0.0
        self.exc_c = 0.0
        self.bc = np.zeros(3)
        self.res_w = np.zeros(N_STREAMS)
        self.res_e2 = np.zeros(N_STREAMS)
        self.res_hist = np.zeros((N_STREAMS, N_LAGS))
        self.res_cov = np.zeros((N_STREAMS, N_LAGS))
        self.held: list = []  # the outlier gate's two newest arrivals (older first), waiting for neighbours
        self.gate_s = np.zeros(4)
        self.gate_n = 0.0
        self.outliers = np.zeros(4)
        self.clamped = 0.0
        # the force balance with observed pressures (monitor.force_observer): filters, normal equations
        self.obs_in = np.zeros((SG_HALF + 1, N_OBS))  # newest first
        self.svf_o = np.zeros((N_OBS, OBS_STATE))
        self.ne_a = np.zeros((N_OBS_PARAMS, N_OBS_PARAMS))
        self.ne_b = np.zeros(N_OBS_PARAMS)
        self.ne_yy = 0.0
        self.th_o = np.zeros(N_OBS_PARAMS)
        self.rows_o = 0.0
        self.obs_sgn = np.zeros(3)  # rows with F[sign(x2)] > 0, < 0, reference fits made
        self.obs_ic = 0.0
        self.obs_kl = 0.0
        self.obs_sol = np.zeros(4)  # the latest solution's B + f_v, f_c and variances (monitor.estimates)
        # the valve's static gain (monitor.equation_rows.static_gain_rows)
        self.svf_k = np.zeros((2, SVF_STATE))
        self.th_k, self.P_k = np.zeros(3), np.eye(3) * o.p0
        self.rows_k = 0.0
        self.since_step = 0.0
        self.obs_step = 0.0

    # -- pieces -----------------------------------------------------------------------------

    def _at(self, lag: int, ch: int) -> float:
        return self.ring[(self.n - 1 - lag) % RING, ch]

    def _residual(self, stream: int, e: float, lam: float) -> None:
        self.res_w[stream] = lam * self.res_w[stream] + 1.0
        self.res_e2[stream] = lam * self.res_e2[stream] + e * e
        self.res_cov[stream] = lam * self.res_cov[stream] + e * self.res_hist[stream]
        self.res_hist[stream] = np.concatenate(([e], self.res_hist[stream][:-1]))

    def _noise_update(self) -> None:
        # running mean of squared 4th differences: D4_VARIANCE_GAIN times the noise variance
        if self.n - 1 < 4:
            return
        self.noise_n += 1.0
        w = 1.0 / min(self.noise_n, self.options.noise_window)
        last5 = np.array([[self._at(lag, ch) for ch in range(1, 5)] for lag in range(5)])
        d4 = np.array([1.0, -4.0, 6.0, -4.0, 1.0]) @ last5
        v = d4 * d4
        if self.noise_n > 50.0:
            v = np.where(v > 100.0 * self.noise, 100.0 * self.noise, v)
        self.noise = self.noise + w * (v - self.noise)

    def _valve(self) -> None:
        c, o = self.config, self.options
        du = np.array([c.K_p * (self._at(j, 0) - c.K_f * self._at(j, 1)) for j in range(3)])
        y = self._at(0, 4) / X5_NOM
        phi = np.concatenate(([-self._at(1, 4) / X5_NOM, -self._at(2, 4) / X5_NOM], du))
        a1, a2 = self.th_v[0], self.th_v[1]
        stable = abs(a2) < 1.0 and abs(a1) < 1.0 + a2
        use_iv = o.instrumental_variables and self.rows[2] >= o.iv_start and stable
        xh1, xh2 = self.xh
        if use_iv:
            z = np.concatenate(([-xh1, -xh2], du))
        else:
            z = phi.copy()
            xh1, xh2 = -phi[0], -phi[1]
        xh = -a1 * xh1 - a2 * xh2 + self.th_v[2:] @ du
        if not (use_iv and math.isfinite(xh)):
            xh = y
        self.xh = np.array([xh, xh1])
        step = abs(self._at(0, 0) - 2.0 * self._at(1, 0) + self._at(2, 0)) > o.step_tol
        if step:
            return
        self.th_v, self.P_v, e = riv(self.th_v, self.P_v, phi, z, y, o.lam, o.p_max)
        if math.isfinite(e):
            self.rows[2] += 1.0
            self._residual(3, y - phi @ self.th_v, o.lam)

    # -- the streaming contract -------------------------------------------------------------

    def update(self, sample) -> None:
        """Take one sample (ug [V], x1 [m], x3 [Pa], x4 [Pa], x5 [m]); the one two before it is consumed."""
        sample = np.asarray(sample, dtype=np.float64)
        if sample.shape != (N_CH,):
            raise ValueError(f"sample must be (ug, x1, x3, x4, x5), got shape {sample.shape}")
        self.held.append(sample.copy())
        if len(self.held) < 3:
            return
        g1 = self.held.pop(0)
        if self.n >= 1 and self.options.outlier_gate > 0:
            g1 = self._gate(g1, self.held[0], self.held[1])
        self._consume(g1)

    def _gate(self, mid: np.ndarray, right: np.ndarray, far: np.ndarray) -> np.ndarray:
        """A sensor value that jumps away from both neighbours by far more than usual: their mean;
        two that sit together away from both sides: the line between the sides (``right``, the
        next sample, is replaced in place)."""
        self.gate_n += 1.0
        w = 1.0 / min(self.gate_n, self.options.noise_window)
        out = mid.copy()
        g2 = self.options.outlier_gate ** 2
        for c in range(4):
            ch = c + 1
            left = self._at(0, ch)
            a, b = mid[ch] - left, mid[ch] - right[ch]
            v = (a + b) ** 2
            if self.gate_n > 50:
                if v > g2 * self.gate_s[c] and a * b > 0 and min(abs(a), abs(b)) > 0.25 * abs(a + b):
                    out[ch] = 0.5 * (left + right[ch])
                    self.outliers[c] += 1.0
                    continue
                if c < 3:  # x1, x3, x4 (not x5: the spool's own peaks last two samples)
                    dev = 0.5 * (mid[ch] + right[ch]) - 0.5 * (left + far[ch])
                    pa, pb = mid[ch] - left, right[ch] - far[ch]
                    if dev * dev > g2 * self.gate_s[c] and pa * dev > 0 and pb * dev > 0 \
                            and min(abs(pa), abs(pb)) > 0.75 * abs(dev) and abs(mid[ch] - right[ch]) < 0.25 * abs(dev) \
                            and abs(far[ch] - left) < 0.25 * abs(dev):
                        out[ch] = left + (far[ch] - left) / 3.0
                        right[ch] = left + 2.0 * (far[ch] - left) / 3.0
                        self.outliers[c] += 2.0
                        continue
                v = min(v, 100.0 * self.gate_s[c])
            self.gate_s[c] += w * (v - self.gate_s[c])
        return out

    def _consume(self, sample: np.ndarray) -> None:
        n = self.n
        self.ring[n % RING] = sample
        self.n = n + 1
        self._noise_update()
        if n >= 2:
            self._valve()
        self._chambers(n)
        if n >= 2 * SG_HALF:
            self._force(n)

    def _chambers(self, n: int) -> None:
        """Chamber rows (eq 28-38) from the newest sample, in flow units, two per sample."""
        c, o = self.config, self.options
        x1, x3, x4, x5 = (self._at(0, ch) for ch in (1, 2, 3, 4))
        # each chamber equation divided by its volume: A1 x2 / V1 = d/dt ln V1, so no velocity
        r1, r2 = c.A1 * x1 / c.V10, -c.A2 * x1 / c.V20
        if min(r1, r2) < V_MIN - 1.0:  # a chamber never below V_MIN of its volume
            self.clamped += 1.0
            r1, r2 = max(r1, V_MIN - 1.0), max(r2, V_MIN - 1.0)
        w1, w2 = 1.0 / (1.0 + r1), 1.0 / (1.0 + r2)
        z1, z2 = orifice_z(x5, x3, x4, c.p_s)
        u_c = np.array([x3, x4, math.log1p(r1), math.log1p(r2),
                        w1 * x5 * z1, w2 * x5 * z2, w1 * (x3 - x4), w2 * (x3 - x4), w1 * x3, w2 * x4])
        if o.pressure_observer:  # the observer's inputs at this sample, kept for the force rows' instant
            g1, g2 = c.A1 * w1 / c.V10, c.A2 * w2 / c.V20
            new = [c.A1 * x3 - c.A2 * x4 - c.F_L, c.A1 * u_c[2] - c.A2 * u_c[3], x5 * (g1 * z1 + g2 * z2),
                   -(x3 - x4) * (g1 + g2), -(g1 * x3 - g2 * x4)]
            self.obs_in = np.vstack(([new], self.obs_in[:-1]))
        if n == 0:
            self.svf_c = np.array([svf_init(self.c_mats, u) for u in u_c])
        yc = np.empty((10, 3))
        for i in range(10):
            self.svf_c[i], yc[i] = svf_step(self.c_mats, self.svf_c[i], u_c[i])
        if n < self.warm or self._chambers_rest(yc):
            return
        lam2 = math.sqrt(o.lam)  # two rows per sample, each forgetting by sqrt(lam)
        s1 = THETA_NOM_C / Y_NOM_C
        phi = np.array([c.V10 * yc[0, 1], -yc[4, 0], yc[6, 0], yc[8, 0]]) * s1
        y = -c.V10 * yc[2, 1] / Y_NOM_C
        self.th_c, self.P_c, e = rls(self.th_c, self.P_c, phi, y, lam2, o.p_max)
        ok = math.isfinite(e)
        if ok:
            self.bc[1] = lam2 * self.bc[1] + c.V10 ** 2
            self.bc[2] = lam2 * self.bc[2]
            self._residual(1, y - phi @ self.th_c, lam2)
        phi = np.array([c.V20 * yc[1, 1], yc[5, 0], -yc[7, 0], yc[9, 0]]) * s1
        y = -c.V20 * yc[3, 1] / Y_NOM_C
        self.th_c, self.P_c, e = rls(self.th_c, self.P_c, phi, y, lam2, o.p_max)
        if ok and math.isfinite(e):
            self.rows[1] += 1.0
            self.bc[1] = lam2 * self.bc[1]
            self.bc[2] = lam2 * self.bc[2] + c.V20 ** 2
            self._residual(2, y - phi @ self.th_c, lam2)

    def _chambers_rest(self, yc: np.ndarray) -> bool:
        """The chamber rows pause: the piston still for rest_pause and the pressure rates'
        running mean square within REST_EXCITATION of the sensor noise's (IdentOptions)."""
        if self.rest_pause <= 0:
            return False
        d = math.exp(-self.h / self.options.rest_pause)
        self.exc_c = d * self.exc_c + (1.0 - d) * (yc[0, 1] ** 2 + yc[1, 1] ** 2)
        noise = self._kernels.g_c[1, 1] * (self.noise[1] + self.noise[2]) / D4_VARIANCE_GAIN
        return self.rest >= self.rest_pause and self.exc_c <= REST_EXCITATION * noise

    def _force(self, n: int) -> None:
        """Force balance row (eq 24-27) at the instant SG_HALF back (centred velocity)."""
        c, o = self.config, self.options
        j = np.arange(-SG_HALF, SG_HALF + 1, dtype=float)
        x1_win = np.array([self._at(SG_HALF - int(i), 1) for i in j])
        v = (j @ x1_win) / ((j @ j) * self.h)
        c1, c3, c4 = (self._at(SG_HALF, ch) for ch in (1, 2, 3))
        q1 = c.A1 * c3 - c.A2 * c4 - c.F_L
        sg = float(np.sign(v))
        v_noise = 3.0 * math.sqrt(self.noise[0] / D4_VARIANCE_GAIN / ((j @ j) * self.h * self.h))
        still = abs(v) < max(o.v_stick, v_noise)
        self.slow = 0.0 if still else self.slow + 1.0
        self.rest = self.rest + 1.0 if still else 0.0
        u_f = np.array([c1, q1, sg])
        if n == 2 * SG_HALF:
            self.svf_f = np.array([svf_init(self.f_mats, u) for u in u_f])
        yf = np.empty((3, 3))
        for i in range(3):
            self.svf_f[i], yf[i] = svf_step(self.f_mats, self.svf_f[i], u_f[i])
        self._static_gain(n, c1)
        yo = self._observer_filters(n, c1, c3, c4, self._at(SG_HALF, 4)) if o.pressure_observer else None
        if n - 2 * SG_HALF < self.warm or self.slow < self.guard:
            return
        # skipped while a reversal is inside the filter's memory
        phi = np.array([yf[0, 2], yf[0, 1], yf[2, 0], yf[0, 0], 1.0]) * THETA_NOM_F / Y_NOM_F
        y = yf[1, 0] / Y_NOM_F
        self.th_f, self.P_f, e = rls(self.th_f, self.P_f, phi, y, o.lam, o.p_max)
        if math.isfinite(e):
            self.rows[0] += 1.0
            self.bc[0] = o.lam * self.bc[0] + 1.0
            self._residual(0, y - phi @ self.th_f, o.lam)
        if yo is not None and self.obs_step >= self.obs_step_guard:
            self._observer_row(phi, yo)

    def _static_gain(self, n: int, x1: float) -> None:
        """The valve's static gain: x5 = K_sv du - (2 zeta / omega) x5' - (1 / omega^2) x5'' under the
        force SVF, at the force rows' instant, skipping rows whose filter memory holds a step in ug."""
        c, o = self.config, self.options
        u = np.array([self._at(SG_HALF, 4), c.K_p * (self._at(SG_HALF, 0) - c.K_f * x1)])
        if n == 2 * SG_HALF:
            self.svf_k = np.array([svf_init(self.f_mats, v) for v in u])
            self.since_step = 0.0
            self.obs_step = float(self.obs_step_guard)
        yk = np.empty((2, 3))
        for i in range(2):
            self.svf_k[i], yk[i] = svf_step(self.f_mats, self.svf_k[i], u[i])
        d2 = self._at(SG_HALF - 1, 0) - 2.0 * self._at(SG_HALF, 0) + self._at(SG_HALF + 1, 0)
        self.since_step = 0.0 if abs(d2) > o.step_tol else self.since_step + 1.0
        self.obs_step = 0.0 if abs(d2) > o.step_tol else self.obs_step + 1.0
        if n - 2 * SG_HALF < self.warm or self.since_step < math.ceil(STEP_GUARD / self.h):
            return
        phi = np.array([yk[1, 0], -yk[0, 1], -yk[0, 2]]) * THETA_NOM_K / X5_NOM
        y = yk[0, 0] / X5_NOM
        self.th_k, self.P_k, e = rls(self.th_k, self.P_k, phi, y, o.lam, o.p_max)
        if math.isfinite(e):
            self.rows_k += 1.0
            self._residual(5, y - phi @ self.th_k, o.lam)

    def _observer_filters(self, n: int, x1: float, x3: float, x4: float, x5: float) -> np.ndarray:
        """The observer filter bank (monitor.force_observer) at the force rows' instant: outputs (5, 4)."""
        c, o = self.config, self.options
        r1 = max(c.A1 * x1 / c.V10, V_MIN - 1.0)
        r2 = max(-c.A2 * x1 / c.V20, V_MIN - 1.0)
        v1, v2 = c.V10 * (1.0 + r1), c.V20 * (1.0 + r2)
        z1, z2 = orifice_z(x5, x3, x4, c.p_s)
        u = np.array([c.A1 * x3 - c.A2 * x4 - c.F_L, c.A1 * math.log1p(r1) - c.A2 * math.log1p(r2),
                      x5 * (c.A1 * z1 / v1 + c.A2 * z2 / v2), -(x3 - x4) * (c.A1 / v1 + c.A2 / v2),
                      -(c.A1 * x3 / v1 - c.A2 * x4 / v2)])
        if n == 2 * SG_HALF:
            # Fm and Lc at rest (H's DC gain is 1/w_c), the flows' integral at zero; an earlier
            # start transient's amplitude is eliminated from the normal equations
            wc = o.observer_crossover
            self.svf_o = np.array([np.concatenate(([u[i] / wc if i < 2 else 0.0], np.zeros(3), [u[i]] * 3))
                                   for i in range(N_OBS)])
            k = N_OBS_PARAMS - 1
            d = self.ne_a[k, k]
            if d > 0.0:
                self.ne_yy -= self.ne_b[k] ** 2 / d
                self.ne_b = self.ne_b - self.ne_a[:, k] * self.ne_b[k] / d
                self.ne_a = self.ne_a - np.outer(self.ne_a[:, k], self.ne_a[:, k]) / d
            self.ne_a[k, :] = 0.0
            self.ne_a[:, k] = 0.0
            self.ne_b[k] = 0.0
            self.obs_ic = 1.0
            self.obs_kl = c.A1 ** 2 / v1 + c.A2 ** 2 / v2
        phi_m, g = self.o_mats
        hold = n - 2 * SG_HALF < 2  # the two intervals before the first sample (see obs_bank_step)
        y = np.empty((N_OBS, OBS_ORDER))
        for i in range(N_OBS):
            x = self.svf_o[i]
            y[i] = x[:OBS_ORDER] if hold else phi_m @ x[:OBS_ORDER] + g @ np.array([x[4], x[5], x[6], u[i]])
            self.svf_o[i] = np.concatenate((y[i], x[5:7], [u[i]]))
        if not hold:
            self.obs_ic *= math.exp(-o.observer_crossover * self.h)
        return y

    def _observer_row(self, phi: np.ndarray, yo: np.ndarray) -> None:
        """The force balance with observed pressures: one row into the normal equations."""
        o = self.options
        psi = np.array([-yo[2, 0] * PSI_NOM[0], -yo[3, 0] * PSI_NOM[1], -yo[4, 0] * PSI_NOM[2],
                        yo[1, 1] * PSI_NOM[3]]) / np.float64(Y_NOM_F)
        ph = np.concatenate((phi[:4], psi, [phi[4], self.obs_ic * IC_NOM / np.float64(Y_NOM_F)]))
        y = o.observer_crossover * yo[0, 0] / Y_NOM_F
        if not (np.all(np.isfinite(ph)) and math.isfinite(y)):
            return
        self.ne_a = o.lam * self.ne_a + np.outer(ph, ph)
        self.ne_b = o.lam * self.ne_b + ph * y
        self.ne_yy = o.lam * self.ne_yy + y * y
        self.rows_o += 1.0
        if ph[2] > 0.0:
            self.obs_sgn[0] += 1.0
        elif ph[2] < 0.0:
            self.obs_sgn[1] += 1.0
        if self.rows_o % REF_EVERY == 0 and min(self.obs_sgn[:2]) >= REF_EVERY:
            # reference: the free parameters with psi held at the chamber RLS's current estimate
            cp = self.th_c * THETA_NOM_C
            if cp[0] > 0.0:
                psi = np.array([cp[1] / cp[0], cp[2] / cp[0], cp[3] / cp[0], 1.0 / cp[0]]) / PSI_NOM
                fixed = np.append(psi, self.th_f[4])  # and F_0 at the plain force balance's
                f = list(FREE)
                rhs = self.ne_b[f] - self.ne_a[np.ix_(f, [4, 5, 6, 7, 8])] @ fixed
                self.th_o[f] = np.linalg.solve(self.ne_a[np.ix_(f, f)], rhs)
                self.th_o[4:9] = fixed
                self.obs_sgn[2] += 1.0
        if self.obs_sgn[2] >= 1:
            self._residual(4, y - ph @ self.th_o, o.lam)
        if self.rows_o % OBS_REFRESH == 0:
            # the solve with the chamber prior is read-out arithmetic: the shared one, on the packed state
            st = self.state_row()
            observer_refresh(st, IdentModel.of(self._kernels))
            self.obs_sol = st[O_OBS_SOL:O_OBS_SOL + 4].copy()

    # -- read-out ---------------------------------------------------------------------------

    def state_row(self) -> np.ndarray:
        """The state packed into ``monitor.layout``'s flat row (for the shared read-out)."""
        return pack_state(self)

    def estimates(self) -> tuple[np.ndarray, np.ndarray]:
        """(params, std_errors), each in PARAM_NAMES order (SI), by the shared read-out."""
        p = np.empty(N_PARAMS)
        s = np.empty(N_PARAMS)
        estimates(self.state_row(), IdentModel.of(self._kernels), p, s)
        return p, s
