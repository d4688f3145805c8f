"""IDA's step coefficients against their closed forms at a constant step size.

At a constant step h the history spacings are psi_i = (i + 1) h, so alpha_i = h / psi_i
= 1 / (i + 1), beta_i = 1, sigma_i = i! alpha_1 ... alpha_i = 1 / (i + 1),
gamma_i = H_i / h with H_i = 1 + 1/2 + ... + 1/i, the leading coefficient cj = H_k / h and
the error constant ck = alpha_k = 1 / (k + 1) (alpha_s = -H_k and alpha_0 = -H_k cancel).
"""

import math

import numpy as np
import pytest

from pvgraph.solver.ida import MAX_ORDER, bdf_coefficients


@pytest.mark.parametrize("k", range(1, MAX_ORDER + 1))
def test_constant_step_coefficients_match_closed_forms(k):
    h = 0.37
    psi_old = [(i + 1) * h for i in range(MAX_ORDER + 2)]
    psi, sigma, beta, gamma, cj, ck = bdf_coefficients(h, k, psi_old)
    harmonic = [sum(1.0 / j for j in range(1, i + 1)) for i in range(k + 1)]
    np.testing.assert_allclose(psi[:k + 1], [(i + 1) * h for i in range(k + 1)], rtol=1e-15)
    np.testing.assert_allclose(beta, np.ones(k + 1), rtol=1e-15)
    np.testing.assert_allclose(sigma, [1.0 / (i + 1) for i in range(k + 1)], rtol=1e-14)
    np.testing.assert_allclose(gamma, [harmonic[i] / h for i in range(1, k + 1)], rtol=1e-14)
    assert math.isclose(cj, harmonic[k] / h, rel_tol=1e-14)
    assert math.isclose(ck, 1.0 / (k + 1), rel_tol=1e-12)
    assert psi_old == [(i + 1) * h for i in range(MAX_ORDER + 2)]    # input left unchanged


def test_step_ratio_enters_beta_as_the_ratio_of_spacings():
    """After a change h_old -> h at order 2: beta_1 = h / h_old, beta_2 = beta_1 (h + h_old) / (2 h_old)."""
    h_old, h = 0.2, 0.5
    psi_old = [h_old, 2 * h_old, 3 * h_old, 0.0, 0.0, 0.0, 0.0]
    psi, sigma, beta, gamma, cj, ck = bdf_coefficients(h, 2, psi_old)
    b1 = h / h_old
    b2 = b1 * (h + h_old) / (2 * h_old)
    np.testing.assert_allclose(beta, [1.0, b1, b2], rtol=1e-15)
    np.testing.assert_allclose(psi[:3], [h, h + h_old, h + 2 * h_old], rtol=1e-15)
    assert math.isclose(cj, 1.5 / h, rel_tol=1e-15)
