"""The isolation's steps equal the plain numpy form of their arithmetic to the bit: the balance's chi-square
(the reference's with ``np.linalg.pinv``), a row's chi-squares alone and in a batch, and the fusion of the
evidence (``Isolation.fuse``); each kernel against its reference is ``test_kernel_references``."""

import numpy as np

from ea_gym._kernels.isolation import chi_squares, pseudo_inverse_factors
from ea_gym._kernels.reference import isolation as reference
from ea_gym.diagnosis.training import load_shipped_classifier
from ea_gym.models import spring_mass_damper
from ea_gym.numerics import TINY
from ea_gym.phm import PHMConfig, build_chain
from ea_gym.phm.isolation import balance_chi_square


def chi_square_by_definition(gram, cross, square, windows, columns):
    """``balance_chi_square``: the reference's chi-squares with numpy's pseudo-inverse."""
    return reference.chi_squares(gram, cross, square, windows, np.linalg.pinv(gram, rcond=1e-12, hermitian=True), columns)


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


def test_pseudo_inverse_factors_multiply_to_numpys_pinv():
    gram, _, _ = random_regressions(np.random.default_rng(9), 50)
    left, right_t, tied = pseudo_inverse_factors(*np.linalg.eigh(gram), 1e-12)
    assert not tied
    assert np.matmul(left, right_t.transpose(0, 2, 1)).tobytes() == np.linalg.pinv(gram, rcond=1e-12, hermitian=True).tobytes()


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
