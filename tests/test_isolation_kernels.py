"""The isolation's compiled steps equal the plain numpy form of their arithmetic to the bit: the balance's
chi-square (``np.linalg.pinv``, ``np.sum``) and the fusion of the evidence."""

import numpy as np

from ea_gym._kernels.isolation import (
    balance_log_ratios,
    chi_squares,
    history_sums,
    network_average,
    pseudo_inverse_factors,
    suspect_hypotheses,
)
from ea_gym.diagnosis.training import load_shipped_classifier
from ea_gym.models import spring_mass_damper
from ea_gym.numerics import TINY
from ea_gym.phm import PHMConfig, build_chain
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


def test_chi_squares_explained_sum_is_einsums_for_any_number_of_components():
    # einsum adds the C^2 products in turn from 0 for batches of two or more (a single row with C = 2 it
    # iterates otherwise); the kernel does so for every batch, a row alone included
    rng = np.random.default_rng(12)
    for components in (2, 3, 4, 6):
        gram, cross, square = random_regressions(rng, 200, components)
        inverse = np.linalg.pinv(gram, rcond=1e-12, hermitian=True)
        windows = rng.integers(1, 60, 200)
        columns = np.arange(components)
        chi2 = chi_squares(gram, cross, square, windows, inverse, columns)
        expected = chi_square_by_definition(gram, cross, square, windows, columns)
        assert chi2.tobytes() == expected.tobytes()
        one = [slice(m, m + 1) for m in range(200)]
        alone = np.concatenate([chi_squares(gram[m], cross[m], square[m], windows[m], inverse[m], columns) for m in one])
        assert alone.tobytes() == chi2.tobytes()


def test_balance_log_ratios_equal_the_numpy_form_of_the_balance_evidence():
    rng = np.random.default_rng(13)
    n, span, windows_per_step, inflation = 50, 25, 3, 2.7
    gram, cross, square = random_regressions(rng, 30)
    square[:2] = np.nan  # NaN chi-squares propagate through the smallest
    rows = rng.permutation(n)[:30]
    steps = rng.integers(0, 60, n)
    inverse = np.linalg.pinv(gram, rcond=1e-12, hermitian=True)
    for columns in (np.array([0, 1, 2]), np.array([2, -1, 0, 1])):
        windows = np.minimum(steps[rows], span) * windows_per_step
        chi2 = chi_square_by_definition(gram, cross, square, windows, columns)
        expected = np.zeros((n, 1 + len(columns)))
        expected[rows] = -0.5 * (chi2 - np.minimum.reduce(chi2, axis=1, keepdims=True)) / inflation
        got = balance_log_ratios(gram, cross, square, inverse, steps, rows, span, windows_per_step, columns, inflation, n)
        assert np.isnan(got[rows[:2]]).all() and got.tobytes() == expected.tobytes()


def test_pseudo_inverse_factors_multiply_to_numpys_pinv():
    gram, _, _ = random_regressions(np.random.default_rng(9), 50)
    left, right_t, tied = pseudo_inverse_factors(*np.linalg.eigh(gram), 1e-12)
    assert not tied
    assert np.matmul(left, right_t.transpose(0, 2, 1)).tobytes() == np.linalg.pinv(gram, rcond=1e-12, hermitian=True).tobytes()


def test_history_sums_equal_numpys_sums_of_the_rows_windows():
    rng = np.random.default_rng(10)
    backing = rng.normal(size=(6, 3, 3, 40))
    gram, cross, other = backing[..., 7:27], rng.normal(size=(6, 3, 40))[..., 13:33], rng.normal(size=(6, 4, 30))[..., 5:25]
    rows = np.array([5, 0, 3])
    sums = history_sums(gram, cross, other, rows, 10, False)
    expected = gram[rows, ..., -10:].sum(-1), cross[rows, ..., -10:].sum(-1), other[rows].sum(-1)
    for got, want in zip(sums, expected):
        assert got.tobytes() == want.tobytes()
    for got, want in zip(history_sums(gram, cross, other, rows, 10, True), expected):
        by_system = np.zeros((6,) + want.shape[1:])
        by_system[rows] = want
        assert got.tobytes() == by_system.tobytes()


def test_network_average_moves_the_counted_systems_as_numpy_does():
    rng = np.random.default_rng(11)
    average = rng.random((7, 4))
    counted, predicted = np.array([6, 1, 2]), rng.random((3, 4))
    expected_average = average.copy()
    expected_average[counted] += 0.3 * (predicted - expected_average[counted])
    expected = np.zeros((7, 4))
    expected[:, 0] = 1.0  # "none" for the systems not counted
    expected[counted] = predicted
    assert network_average(predicted, counted, 7, 0.3, average).tobytes() == expected.tobytes()
    assert average.tobytes() == expected_average.tobytes()
    untouched = average.copy()
    none = np.zeros((7, 4))
    none[:, 0] = 1.0
    assert network_average(np.empty((0, 4)), np.array([], dtype=np.int64), 7, 0.3, average).tobytes() == none.tobytes()
    assert average.tobytes() == untouched.tobytes()


def test_suspect_hypotheses_are_all_but_for_a_confident_systems_suspect():
    confident = np.array([False, True, True, False, True])
    isolated = np.array([2, 1, 3, 0, 2])
    expected = np.where(confident[:, None], np.arange(3) == isolated[:, None] - 1, True)
    got = suspect_hypotheses(confident, isolated, 3)
    assert got.dtype == np.bool_ and np.array_equal(got, expected)
    assert suspect_hypotheses(np.zeros(4, dtype=bool), np.zeros(4, dtype=int), 3).all()


def fuse_by_definition(average, previous, floor, weights, threshold, alarm, log_evidence, estimated, balance):
    """``Isolation.fuse`` in plain numpy: belief, suspect, confidence, confident, restarted systems."""
    n, K = average.shape
    total = average.sum(1, keepdims=True)
    network = np.where(total > 0, average / np.where(total > 0, total, 1.0), 1.0 / K)
    best = np.max(log_evidence, axis=1, initial=-np.inf, where=np.isfinite(log_evidence))
    evidence = weights.estimator * (log_evidence - best[:, None])
    evidence = np.where(np.isfinite(evidence), evidence, 0.0)
    log_belief = weights.network * np.log(network + floor) + evidence + weights.balance * balance
    belief = np.exp(log_belief - log_belief.max(1, keepdims=True))
    believed = alarm & (np.any(np.isfinite(log_evidence[:, 1:]), axis=1) | (total[:, 0] > 0))
    diagnosis = np.where(believed[:, None], belief / belief.sum(1, keepdims=True), np.eye(K)[0])
    isolated = np.where(believed, 1 + np.argmax(diagnosis[:, 1:], axis=1), 0)
    changed = np.flatnonzero((isolated != previous) & (isolated > 0))
    changed = changed[~estimated[changed, isolated[changed] - 1]]
    share = diagnosis[np.arange(n), isolated] / np.maximum(diagnosis[:, 1:].sum(1), TINY)
    confident = (isolated > 0) & (share >= threshold)
    return diagnosis, isolated, np.where(isolated > 0, share, 0.0), confident, changed


def test_fuse_equals_its_numpy_definition_to_the_bit():
    rng = np.random.default_rng(11)
    n = 400
    model = spring_mass_damper()
    for kind in ("ea_inversion", "tracking"):
        chain = build_chain(model, PHMConfig(estimator_kind=kind), load_shipped_classifier(model.name), rng, n_systems=n)
        isolation = chain.isolation
        average = rng.dirichlet(np.ones(4), n) * rng.uniform(0, 2, (n, 1))
        average[:40] = 0.0  # before the network's first frame
        average[40:60, 1:] = 0.0  # the network sure of "none"
        log_evidence = rng.normal(0, 30, (n, 4))
        log_evidence[rng.uniform(size=(n, 4)) < 0.2] = np.nan  # hypotheses not fitted yet
        log_evidence[60:70] = np.nan
        log_evidence[70:80, 2] = -np.inf
        log_evidence[80:90, 1:] = log_evidence[80:90, 1:2]  # equal fits
        balance = -rng.exponential(5.0, (n, 4))
        balance[90:100] = 0.0
        alarm = rng.uniform(size=n) < 0.8
        estimated = rng.uniform(size=(n, 3)) < 0.5
        previous = rng.integers(0, 4, n)
        isolation.state.probability_average[:] = average
        isolation.state.isolated[:] = previous
        fusion = isolation.fuse(alarm, log_evidence, estimated, balance)
        config = chain.config
        expected = fuse_by_definition(
            average, previous, config.isolation.network_floor, isolation.weights, config.isolation.confidence, alarm, log_evidence, estimated, balance
        )
        # the cases are all there: restarted, confident and unsure suspects, systems without a belief
        assert len(expected[4]) and expected[3].any() and (~expected[3] & (expected[1] > 0)).any() and (expected[1] == 0).any()
        got = (fusion.belief, fusion.isolated, fusion.confidence, fusion.confident, fusion.restarted)
        for a, b in zip(got, expected):
            assert a.dtype == b.dtype and a.tobytes() == b.tobytes()
        assert np.array_equal(isolation.state.isolated, expected[1]) and np.array_equal(isolation.state.confident, expected[3])
        assert fusion.confident is not isolation.state.confident
