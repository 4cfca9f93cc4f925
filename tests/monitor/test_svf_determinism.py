"""The filter matrices are the same bits on every machine (golden recordings depend on it)."""

import os
import platform
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm

from monitor.svf import expm_det, noise_gram, svf_matrices

_DIGEST = (
    "from monitor.svf import svf_matrices, noise_gram; import hashlib; "
    "m = [svf_matrices(a, 0.01) for a in (25.0, 80.0)]; "
    "print(hashlib.sha256(b''.join(x.tobytes() + noise_gram(x).tobytes() for x in m)).hexdigest())"
)


def _digest(coretype: str | None) -> str:
    env = dict(os.environ)
    env.pop("OPENBLAS_CORETYPE", None)
    if coretype:
        env["OPENBLAS_CORETYPE"] = coretype
    out = subprocess.run([sys.executable, "-c", _DIGEST], env=env, capture_output=True, text=True, timeout=120,
                         cwd=os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"), reason="OpenBLAS core types named here are x86")
def test_filter_matrices_do_not_depend_on_the_blas_kernel():
    # OpenBLAS picks its kernel by CPU; scipy's expm and numpy's @ on top of it gave matrices
    # 1 ulp apart on an AVX-512 machine (SkylakeX) and elsewhere (Haswell), and the golden
    # recordings failed there. Prescott (SSE3) runs on every x86-64 CPU.
    assert _digest("Prescott") == _digest(None)


def test_expm_det_equals_scipy_on_the_filters():
    for a in (5.0, 25.0, 80.0, 300.0):
        n = 3
        c = np.poly(-a * np.ones(n))
        m = np.zeros((7, 7))
        m[:2, 1:3] = np.eye(2)
        m[2, :3] = -c[1:][::-1]
        m *= 0.01
        m[2, 3] = a ** 3 * 0.01
        m[3, 4] = m[4, 5] = m[5, 6] = 1.0
        ref = expm(m)
        big = np.abs(ref) > 1e-10
        # scipy's own error at 300 rad/s is 2e-12 (against a 50-digit reference; ours 3.5e-15)
        np.testing.assert_allclose(expm_det(m)[big], ref[big], rtol=5e-12)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 6), st.floats(0.01, 20.0))
def test_expm_det_matches_scipy_on_random_matrices(seed, n, scale):
    m = np.random.default_rng(seed).normal(size=(n, n)) * scale / n
    ref = expm(m)
    # rounding grows with the squarings and the matrix's conditioning; both methods are within
    # a few ulp of the norm of the result here
    np.testing.assert_allclose(expm_det(m), ref, rtol=0, atol=1e-11 * np.abs(ref).max())


def test_noise_gram_is_symmetric_and_matches_numpy():
    m = svf_matrices(80.0, 0.01)
    g = noise_gram(m)
    assert np.array_equal(g, g.T)
    from monitor.svf import impulse_response
    r = impulse_response(m)
    np.testing.assert_allclose(g, r.T @ r, rtol=1e-13)
