"""The compiled monitor and signature kernels equal a straightforward numpy computation to round-off."""

import warnings

import numpy as np
import pytest

from ea_gym.diagnosis.monitor import Monitor, MonitorWindow
from ea_gym.models import rlc_circuit, spring_mass_damper
from ea_gym.phm.history import MonitorHistory, push_window
from ea_gym.phm.inversion import EAInversion
from ea_gym.phm.inversion_estimator import push_median
from ea_gym.threads import MIN_ROWS_PER_THREAD, kernel_threads, set_kernel_threads


def _close(actual, expected):
    scale = np.max(np.abs(expected)) if np.size(expected) else 1.0
    np.testing.assert_allclose(actual, expected, rtol=1e-12, atol=1e-12 * scale)


def _reference_powers(monitor, signals, start):
    """Filter whole signals, nominal laws through the junction matrices, I elements by I0 f df/dt."""
    smooth = monitor.filter(signals)[..., start:]
    channels = [j for j, _ in monitor._inertance.values()]
    slope = monitor.filter(signals[..., channels, :], deriv=1)[..., start:]
    states = smooth[..., :-1, :] * monitor._to_state[:, None]
    bonds = np.einsum("bs,...st->...bt", monitor._Cy, states) + monitor._Dy[:, 0][:, None] * smooth[..., None, -1, :]
    effort, flow = monitor.model.state_space.element_signals(np.moveaxis(bonds, -2, -1))
    power = {name: effort[name] * flow[name] for name in effort}
    for k, (name, (j, inertance)) in enumerate(monitor._inertance.items()):
        power[name] = inertance * smooth[..., j, :] * slope[..., k, :]
    return np.stack([power[name] for name in monitor.elements], axis=-2), smooth


def _sums(x, n):
    return x[..., : x.shape[-1] // n * n].reshape(x.shape[:-1] + (-1, n)).sum(-1)


def _reference_update(monitor, context, measured, reference, load):
    """One chunk as the monitor processes it, and the next context."""
    S, h, n = monitor.config.smoothing, monitor.h, len(measured)
    both = np.concatenate([np.concatenate([measured, reference]), np.concatenate([load, load])[:, None]], axis=1)
    mirrored = both[..., 1 : S + 1][..., ::-1]
    lead = mirrored if context is None else np.where(np.isnan(context), mirrored, context)
    power, smooth = _reference_powers(monitor, np.concatenate([lead, both], axis=-1), S)
    ea = _sums(0.5 * (np.abs(power[..., :-1]) + np.abs(power[..., 1:])) * h, monitor.n_sub)
    energy = _sums(0.5 * (power[..., :-1] + power[..., 1:]) * h, monitor.n_sub)
    for name, (j, inertance) in monitor._inertance.items():
        energy[:, monitor.elements.index(name)] = 0.5 * inertance * np.diff(smooth[:, j, :: monitor.n_sub] ** 2, axis=-1)
    balance = energy[:, monitor._source_index].sum(1) - energy[:, monitor.component_index].sum(1)
    residual = _sums(balance[:n] - balance[n:], monitor.n_balance)
    stored = _sums(energy[:n, monitor.component_index], monitor.n_balance)
    raw = measured[..., 1:]
    noise = np.stack([((raw - smooth[:n, :-1, 1:]) ** 2).sum(-1), (raw**2).sum(-1)], axis=1)
    expected = {
        "ea": ea[:n], "ea_reference": ea[n:], "balance": residual, "signals": smooth[:n, :-1], "noise": noise,
        "gram": np.einsum("nis,njs->nsij", stored, stored), "cross": np.einsum("nis,ns->nsi", stored, residual),
    }
    return expected, both[..., -S - 1 : -1]


@pytest.mark.parametrize("make_model", [spring_mass_damper, rlc_circuit])
def test_chunks_with_context_and_fresh_systems_match_numpy(make_model):
    model = make_model()
    rng = np.random.default_rng(3)
    n, nx, L = 5, len(model.state_names), 100
    monitor = Monitor(model, 0.01, n_systems=n)
    context = None
    for chunk in range(4):
        if chunk == 2:  # systems 1 and 3 start over: their context is forgotten
            fresh = np.isin(np.arange(n), [1, 3])
            monitor.reset(fresh)
            context[np.concatenate([fresh, fresh])] = np.nan
        measured, reference = rng.standard_normal((2, n, nx, L + 1))
        load = rng.standard_normal((n, L + 1))
        window = monitor.update(measured, reference, load)
        expected, context = _reference_update(monitor, context, measured, reference, load)
        for key, value in expected.items():
            _close(getattr(window, key), value)


def test_update_is_the_same_on_one_kernel_thread_and_on_two():
    # two threads' worth of systems and 8: one part in blocks of 32 on one thread, parts of 34 on two; the
    # loads repeat (in fours) across the parts' boundaries, and systems start over in the middle
    model = spring_mass_damper()
    rng = np.random.default_rng(5)
    n, nx, L = 2 * MIN_ROWS_PER_THREAD + 8, len(model.state_names), 100
    monitors = {threads: Monitor(model, 0.01, n_systems=n) for threads in (1, 2)}
    previous = kernel_threads()
    try:
        for chunk in range(3):
            measured, reference = rng.standard_normal((2, n, nx, L + 1))
            load = np.repeat(rng.standard_normal((n // 4, L + 1)), 4, axis=0)
            windows = {}
            for threads, monitor in monitors.items():
                set_kernel_threads(threads)
                if chunk == 2:
                    monitor.reset(np.arange(n) % 3 == 0)
                windows[threads] = monitor.update(measured, reference, load)
            for name in ("ea", "ea_reference", "gram", "cross", "balance", "signals", "noise"):
                np.testing.assert_array_equal(getattr(windows[1], name), getattr(windows[2], name))
    finally:
        set_kernel_threads(previous)


def test_a_systems_window_does_not_depend_on_its_batch():
    """A system alone, and the same system in batches whose filters run more signals side by side (fewer
    than the lanes, several groups of them, loads shared or not), gets the same bits."""
    model = spring_mass_damper()
    rng = np.random.default_rng(6)
    nx, L = len(model.state_names), 100
    for n in (1, 3, 40):
        measured, reference = rng.standard_normal((2, n, nx, L + 1))
        load = rng.standard_normal((n, L + 1))
        load[n // 2 :] = load[0]
        batch = Monitor(model, 0.01, n_systems=n)
        alone = Monitor(model, 0.01)
        for _ in range(2):
            windows = batch.update(measured, reference, load), alone.update(measured[-1:], reference[-1:], load[-1:])
            for name in ("ea", "ea_reference", "gram", "cross", "balance", "signals", "noise"):
                np.testing.assert_array_equal(getattr(windows[0], name)[-1:], getattr(windows[1], name), err_msg=name)


def test_powers_and_signature_match_numpy_for_shared_and_distinct_loads():
    model = spring_mass_damper()
    monitor = Monitor(model, 0.01)
    estimator = EAInversion(monitor)
    rng = np.random.default_rng(4)
    signals = rng.standard_normal((4, 3, 3, 200))
    signals[:2, :, -1] = signals[:2, :1, -1]  # candidates of one system share the load
    for start in (0, 51):
        power, smooth = monitor.powers(signals, start)
        expected_power, expected_smooth = _reference_powers(monitor, signals, start)
        _close(power, expected_power)
        _close(smooth, expected_smooth)
    h, components, sources = monitor.h, estimator._components, estimator._sources
    ea = (0.5 * (np.abs(power[..., components, :-1]) + np.abs(power[..., components, 1:])) * h).sum(-1)
    net = power[..., sources, :].sum(-2) - power[..., components, :].sum(-2)
    balance = 0.5 * (net[..., :-1] + net[..., 1:]).sum(-1) * h
    _close(estimator.signature(power), np.concatenate([ea, balance[..., None]], axis=-1))


def test_scratch_results_are_overwritten_but_plain_results_are_not():
    monitor = Monitor(spring_mass_damper(), 0.01)
    a, b = np.random.default_rng(5).standard_normal((2, 2, 3, 120))
    kept, _ = monitor.powers(a, 51)
    first = kept.copy()
    monitor.powers(b, 51, scratch=True)
    np.testing.assert_array_equal(kept, first)


def test_non_finite_power_is_rejected():
    monitor = Monitor(spring_mass_damper(), 0.01)
    measured = np.ones((1, 2, 101))
    measured[0, 0, 50] = np.inf
    with pytest.raises(ValueError, match="finite"):
        monitor.update(measured, np.ones((1, 2, 101)), np.ones((1, 101)))


def test_pushed_median_equals_numpy_nanmedian():
    rng = np.random.default_rng(6)
    for width in (1, 2, 3, 4, 5):
        raw = rng.standard_normal((6, 3, width))
        raw[rng.random(raw.shape) < 0.4] = np.nan
        rows, columns = np.nonzero(rng.random((6, 3)) < 0.7)
        values = rng.standard_normal(len(rows))
        values[::4] = np.nan
        expected_raw = raw.copy()
        expected_raw[rows, columns] = np.concatenate([raw[rows, columns, 1:], values[:, None]], axis=-1)
        median = np.zeros((6, 3))
        expected = median.copy()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN windows: NaN, as the kernel gives
            expected[rows, columns] = np.nanmedian(expected_raw[rows, columns], axis=-1)
        push_median(raw, rows, columns, values, median)
        np.testing.assert_array_equal(raw, expected_raw)
        np.testing.assert_array_equal(median, expected)


def test_pushed_history_equals_concatenating_and_dropping():
    """The sliding window gives the history a fresh array would, through its moves back to the start,
    writes into it between pushes (a chain reset) and a buffer that is not yet a window."""
    rng = np.random.default_rng(8)
    for length, k in ((7, 1), (7, 3), (6, 6), (403, 100)):
        buffer = rng.standard_normal((4, 2, length))
        expected = buffer.copy()
        for step in range(3 * length):
            new = rng.standard_normal((4, 2, k))
            expected = np.concatenate([expected, new], axis=-1)[..., k:]
            buffer = push_window(buffer, new)
            np.testing.assert_array_equal(buffer, expected)
            if step % 5 == 2:
                buffer[1] = expected[1] = rng.standard_normal((2, length))
        buffer = push_window(buffer.copy(), new)  # a plain array again
        np.testing.assert_array_equal(buffer, np.concatenate([expected, new], axis=-1)[..., k:])


def test_recorded_history_equals_the_numpy_sums_pushed():
    """``MonitorHistory.record`` (compiled sums and pushes) gives what pushing numpy's sums of every step
    gives, through the windows' moves back and resets."""
    rng = np.random.default_rng(9)
    n, elements, subs, windows, components, states = 5, 4, 10, 10, 3, 2
    dissipators = np.array([1, 3])
    history = MonitorHistory.new(n, elements, components, states, subs=3 * subs, frame_steps=3, regression_steps=4, balance_steps=6,
                                 evidence_steps=5)
    expected = MonitorHistory.new(n, elements, components, states, subs=3 * subs, frame_steps=3, regression_steps=4, balance_steps=6,
                                  evidence_steps=5)
    for step in range(25):
        window = MonitorWindow(
            ea=rng.uniform(0, 1, (n, elements, subs)), ea_reference=rng.uniform(0, 1, (n, elements, subs)),
            gram=rng.standard_normal((n, windows, components, components)), cross=rng.standard_normal((n, windows, components)),
            balance=rng.standard_normal((n, windows)) * 10.0 ** rng.uniform(-3, 3, (n, windows)), signals=np.empty(0),
            noise=rng.uniform(0, 1, (n, 2, states)),
        )
        history.record(window, 0.5, dissipators)
        e = expected
        e.time, e.steps = e.time + 0.5, e.steps + 1
        e.ea, e.ea_reference = push_window(e.ea, window.ea), push_window(e.ea_reference, window.ea_reference)
        e.gram = push_window(e.gram, window.gram.sum(axis=1)[..., None])
        e.cross = push_window(e.cross, window.cross.sum(axis=1)[..., None])
        e.balance = push_window(e.balance, window.balance.sum(-1)[:, None])
        e.balance_square = push_window(e.balance_square, (window.balance**2).sum(-1)[:, None])
        e.dissipated = push_window(e.dissipated, window.ea_reference[:, dissipators].sum((1, 2))[:, None])
        e.noise = push_window(e.noise, window.noise[..., None])
        for name in ("time", "steps", "ea", "ea_reference", "gram", "cross", "balance", "balance_square", "dissipated", "noise"):
            np.testing.assert_array_equal(getattr(history, name), getattr(e, name), err_msg=name)
        if step == 7:
            mask = np.arange(n) % 2 == 0
            history.reset(mask)
            e.reset(mask)
