"""White sensor noise seen through 4th differences: the two constants that turn their statistics
into a noise variance.

The 4th difference d4(k) = x(k) - 4 x(k-1) + 6 x(k-2) - 4 x(k-3) + x(k-4) of white noise of
variance s^2 has variance s^2 times the sum of its squared coefficients,
1 + 16 + 36 + 16 + 1 = 70 (= C(8, 4)); a smooth signal's 4th difference is small (h^4 x''''),
so mean(d4^2) / 70 estimates s^2. Where transients must not count, the median replaces the
mean: d4^2 / (70 s^2) of Gaussian noise is chi2(1), whose median is CHI2_1_MEDIAN times its
mean of 1.
"""

D4_VARIANCE_GAIN = 70.0
"""Variance of a 4th difference of white noise over the noise's variance [-]."""

CHI2_1_MEDIAN = 0.4549364231195728
"""Median of chi2(1) [-]: (Phi^-1(3/4))^2, the squared upper quartile of N(0, 1)."""
