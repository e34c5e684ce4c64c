"""The balance evidence's compiled steps equal the plain numpy form of the chi-square (``np.linalg.pinv``,
``np.sum``) to the bit."""

import numpy as np

from ea_gym._kernels.isolation import balance_sums, pseudo_inverse_factors
from ea_gym.numerics import TINY
from ea_gym.phm.isolation import balance_chi_square


def chi_square_by_definition(gram, cross, square, windows, columns):
    """``balance_chi_square`` in plain numpy."""
    C = gram.shape[-1]
    explained = np.einsum("ni,nij,nj->n", cross, np.linalg.pinv(gram, rcond=1e-12, hermitian=True), cross)
    variance = np.maximum(square - explained, TINY) / np.maximum(windows - C, 1)
    single = cross**2 / np.maximum(np.diagonal(gram, axis1=-2, axis2=-1), TINY)
    chi2 = np.empty((len(square), 1 + len(columns)))
    chi2[:, 0] = explained
    chi2[:, 1:] = explained[:, None] - np.where(columns >= 0, single[:, columns], explained[:, None])
    with np.errstate(over="ignore"):  # a regression that explains everything: variance TINY, chi-squares inf
        chi2 = np.maximum(chi2, 0.0) / variance[:, None]
    chi2[:, 1:] = np.where(columns >= 0, chi2[:, 1:], chi2.min(1, keepdims=True))
    return chi2


def random_regressions(rng, n, components=3):
    """Sums of n regressions, some of them rank-deficient (a component never excited), with residuals
    the components explain in part."""
    energies = rng.normal(size=(n, components, 40)) * 10.0 ** rng.uniform(-3, 3, (n, components, 1))
    energies[: n // 4, rng.integers(components)] = 0.0
    energies[n // 4 : n // 3, 1] = 1e-9 * energies[n // 4 : n // 3, 0]  # nearly collinear
    residual = np.einsum("nct,nc->nt", energies, rng.normal(size=(n, components)) * 0.01) + rng.normal(size=(n, 40))
    return energies @ energies.transpose(0, 2, 1), np.einsum("nct,nt->nc", energies, residual), (residual**2).sum(-1)


def test_balance_chi_square_equals_its_numpy_definition_to_the_bit():
    rng = np.random.default_rng(8)
    gram, cross, square = random_regressions(rng, 300)
    windows = rng.integers(1, 60, 300)
    for columns in (np.array([0, 1, 2]), np.array([2, -1, 0, 1])):
        expected = chi_square_by_definition(gram, cross, square, windows, columns)
        assert balance_chi_square(gram, cross, square, windows, columns).tobytes() == expected.tobytes()
    # equal eigenvalues (a multiple of the identity, nothing at all): numpy's sort decides, numpy's pinv is used
    gram[:2] = [2.0 * np.eye(3), np.zeros((3, 3))]
    assert pseudo_inverse_factors(*np.linalg.eigh(gram[:2]), 1e-12)[2]
    columns = np.array([0, 1, 2])
    expected = chi_square_by_definition(gram, cross, square, windows, columns)
    assert balance_chi_square(gram, cross, square, windows, columns).tobytes() == expected.tobytes()


def test_pseudo_inverse_factors_multiply_to_numpys_pinv():
    gram, _, _ = random_regressions(np.random.default_rng(9), 50)
    left, right_t, tied = pseudo_inverse_factors(*np.linalg.eigh(gram), 1e-12)
    assert not tied
    assert np.matmul(left, right_t.transpose(0, 2, 1)).tobytes() == np.linalg.pinv(gram, rcond=1e-12, hermitian=True).tobytes()


def test_balance_sums_equal_numpys_sums_of_the_rows_windows():
    rng = np.random.default_rng(10)
    backing = rng.normal(size=(6, 3, 3, 40))
    gram, cross, square = backing[..., 7:27], rng.normal(size=(6, 3, 40))[..., 13:33], rng.normal(size=(6, 10))
    rows = np.array([5, 0, 3])
    sums = balance_sums(gram, cross, square, rows, 10)
    expected = gram[rows, ..., -10:].sum(-1), cross[rows, ..., -10:].sum(-1), square[rows].sum(-1)
    for got, want in zip(sums, expected):
        assert got.tobytes() == want.tobytes()
