"""Inputs for ``test_kernel_references``: for each kernel "module.name", a function of a generator giving its
arguments, the tolerance its reference states (None: to the bit) and a check that the inputs reach the
kernel's branches."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ea_gym._kernels.expm import PADE13
from ea_gym._kernels.filter_records import FilterBank, FilterSettings, FilterStates, HypothesisModels, TrackedSignals, TrackOutputs
from ea_gym._kernels.monitor import ChunkOutputs, ChunkSignals, EnergyWindows, NominalLaws, Smoothing
from ea_gym._kernels.multisine import multisine_rotations
from ea_gym._kernels.smoothing import LANES
from ea_gym._kernels.summation import summation_scratch
from ea_gym.diagnosis.smoothing import SavitzkyGolay
from ea_gym.numerics import TINY

H = 0.01  # sample period (s)


def reached(got: Any, args: tuple) -> None:
    """No branch condition to check beyond the comparison itself."""


@dataclass(frozen=True)
class Case:
    args: tuple
    rtol: float | None = None  # None: to the bit
    atol: float = 0.0
    check: Callable[[Any, tuple], None] = reached
    workspaces: tuple[int, ...] = ()  # the arguments that are the kernel's working space, not its results


CASES: dict[str, Callable[[np.random.Generator], Case]] = {}


def case(name: str) -> Callable[[Callable[[np.random.Generator], Case]], Callable[[np.random.Generator], Case]]:
    def register(build: Callable[[np.random.Generator], Case]) -> Callable[[np.random.Generator], Case]:
        CASES[name] = build
        return build

    return register


# --- activity, summation, ledger, rows, wear ----------------------------------------------------------


@case("activity.trapezoid_activity")
def _(rng: np.random.Generator) -> Case:
    return Case((rng.standard_normal(1001), 100, 900, H), rtol=1e-13)


@case("activity.interval_activities")
def _(rng: np.random.Generator) -> Case:
    return Case((rng.standard_normal((3, 257)), H))


def shares_input(rng: np.random.Generator, rows: int) -> np.ndarray:
    ea = rng.uniform(0.0, 2.0, (rows, 5))
    ea[0, [1, 3, 4]] = 0.0  # a row at rest: 1 / C each
    return ea


@case("activity.component_shares")
def _(rng: np.random.Generator) -> Case:
    columns = np.array([1, 3, 4])
    return Case((shares_input(rng, 6), columns, np.zeros((6, 3))), check=lambda got, args: np.testing.assert_array_equal(args[2][0], 1 / 3))


@case("activity.summed_shares")
def _(rng: np.random.Generator) -> Case:
    sub_ea = rng.uniform(0.0, 2.0, (1, 5, 200))  # one system: real and reference rows, a sum of numpy's halving
    sub_ea[0, 2, 7] = -1.0  # a negative EA: its component reported, nothing written
    return Case((sub_ea, sub_ea * 1.1, np.array([0, 2, 4]), np.zeros((2, 5)), np.zeros((2, 3))), check=lambda got, args: got == 1)


@case("summation.numpy_sum")
def _(rng: np.random.Generator) -> Case:
    return Case((rng.standard_normal(1000), 3, 997, summation_scratch()), workspaces=(3,))


@case("ledger.take_orders")
def _(rng: np.random.Generator) -> Case:
    actions = rng.integers(0, 4, 30)
    actions[20] = 7  # refused: the orders after it unwritten
    return Case((actions, 4, rng.integers(0, 2, 30), np.full(30, -1)), check=lambda got, args: not got)


@case("ledger.outside_limits")
def _(rng: np.random.Generator) -> Case:
    theta = rng.uniform(0.0, 2.0, (40, 4))
    theta[3, 1] = np.nan  # NaN is inside
    return Case((theta, np.array([1, 3]), np.array([0.2, 0.3]), np.array([1.8, 1.9]), rng.random(40) < 0.7, np.zeros(40, dtype=bool)),
                check=lambda got, args: got and not args[5].all())


@case("ledger.close_step")
def _(rng: np.random.Generator) -> Case:
    n = 20
    failed = rng.random(n) < 0.3
    return Case((rng.standard_normal((4, n)), 1, 2.5, rng.integers(0, 3, n), rng.uniform(0, 100, n), rng.integers(0, 10, n),
                 rng.random(n) < 0.3, failed, 10.0, 8, True, np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)),
                check=lambda got, args: args[11].any() and args[12].any())


@case("rows.changed_rows")
def _(rng: np.random.Generator) -> Case:
    theta = rng.standard_normal((8, 3))
    kept = theta.copy()
    kept[1, 2] = -0.0 if theta[1, 2] == 0 else theta[1, 2] * 2
    theta[4, 0], kept[4, 0] = 0.0, -0.0  # the same value, another sign: changed
    theta[6, 1] = kept[6, 1] = np.nan  # NaN: never the same
    return Case((theta, kept), check=lambda got, args: list(got) == [1, 4, 6])


@case("rows.replace_rows")
def _(rng: np.random.Generator) -> Case:
    return Case((np.array([4, 1]), np.array([1, 0]), rng.standard_normal((2, 3)), rng.standard_normal((2, 2, 2)), rng.standard_normal((2, 2, 3)),
                 np.zeros((6, 3)), np.zeros((6, 2, 2)), np.zeros((6, 2, 3))))


def wear_case(rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    """300 processes on 120 systems of 4 parameter columns: several processes per system (the world where every
    part ages), the processes' systems in no order."""
    n, systems = 120, rng.integers(0, 120, 300)
    values = rng.uniform(0.5, 1.5, (n, 4))
    parts = rng.integers(0, 3, len(systems))
    clock = rng.uniform(0.0, 100.0, n)
    arrival = clock[systems] + rng.uniform(-5.0, 3.0, len(systems))
    arrival[::9] = np.inf  # no fault yet
    velocity = rng.normal(0.0, 0.01, len(systems))
    velocity[::7] = 0.0
    return values, systems, parts, clock, arrival, velocity


@case("wear.steady_wear")
def _(rng: np.random.Generator) -> Case:
    values, systems, parts, clock, arrival, velocity = wear_case(rng)
    running = np.arange(len(values)) % 5 != 2
    return Case((values, systems, np.array([3, 0, 2]), running, parts, arrival, velocity, clock, 1.0, np.array([True, False, True]),
                 np.empty(len(systems))),
                check=lambda got, args: len(got) > 0)


@case("wear.mean_trend_rul")
def _(rng: np.random.Generator) -> Case:
    values, systems, parts, clock, arrival, velocity = wear_case(rng)
    values[::5] = 2.0  # past the upper limits
    limits = np.array([[0.2, 1.8], [0.4, 1.6], [0.1, 1.9]])
    return Case((values, systems, np.array([2, 0, 3]), parts, limits, velocity, arrival, clock, np.empty(len(systems))),
                check=lambda got, args: np.isinf(args[8]).any() and (args[8] == 0).any())


# --- joint filter ---------------------------------------------------------------------------------


@case("joint.joint_samples")
def _(rng: np.random.Generator) -> Case:
    """Two systems, nx = 2, D = 3 (theta near 100, 10, 0.5), five samples: a flow read through an estimated
    inertia and one through a nominal one; the third parameter's upper bound below its estimate (clipped)."""
    n, nx, d, nw, samples = 2, 2, 3, 4, 5
    size = nx + 2 * d
    M0 = np.concatenate([np.eye(nx) + 0.01 * rng.standard_normal((n, nx, nx)), 0.01 * rng.standard_normal((n, nx, nw))], axis=2)
    dM = 1e-3 * rng.standard_normal((n, d, nx, nx + nw))
    theta = np.array([100.0, 10.0, 0.5])
    anchor = theta * (1.0 + 0.01 * rng.standard_normal((n, d)))
    theta_now = anchor * (1.0 + 1e-3 * rng.standard_normal((n, d)))
    x = np.concatenate([rng.standard_normal((n, nx)), theta_now, 1e-3 * rng.standard_normal((n, d))], axis=1)
    root = 0.1 * rng.standard_normal((n, size, size))
    P = root @ root.transpose(0, 2, 1) + 1e-4 * np.eye(size)
    Q = np.repeat(np.diag(1e-6 * rng.uniform(0.5, 1.5, size))[None], n, axis=0)
    lo, hi = 0.5 * theta, np.array([150.0, 15.0, 0.49])
    return Case(
        (M0, dM, anchor, rng.standard_normal((n, samples, nw)), np.array([H, 0.0]), Q, rng.standard_normal((n, nx, samples + 1)),
         rng.uniform(0.5, 1.5, (n, nx)) * 1e-2, np.array([[0, 1], [1, -1]], dtype=np.int64), np.array([10.0, 2.0]), lo, hi, x, P,
         np.empty((n, samples, nx)), np.empty((n, samples, nx, nx))),
        rtol=1e-9, atol=1e-13,
    )


# --- prognosis, detection, history -------------------------------------------------------------------

Z2 = 1.959963984540054**2


def drift_case(rng: np.random.Generator, m: int) -> tuple[np.ndarray, ...]:
    value = 100.0 + rng.normal(0.0, 8.0, m)
    drift = rng.normal(0.0, 0.5, m)
    drift[::7] = 0.0  # no drift: no End of Life
    drift[1::11] = -0.0
    root = rng.normal(0.0, 1.0, (m, 2, 2)) * np.array([2.0, 0.05])[:, None]
    covariance = root @ root.transpose(0, 2, 1)
    covariance[::13] = 0.0  # certain values: a = rate^2
    covariance[5::17, 1, 1] = drift[5::17] ** 2 / Z2  # a = 0 exactly where it can be
    return value, drift, covariance[:, 0, 0].copy(), covariance[:, 0, 1].copy(), covariance[:, 1, 1].copy()


@case("prognosis.drift_ends")
def _(rng: np.random.Generator) -> Case:
    m = 2000
    t = rng.uniform(0.0, 500.0, m)
    return Case((*drift_case(rng, m), np.full(m, 90.0), np.full(m, 110.0), t, rng.uniform(0.0, 0.05, m), Z2, np.empty((m, 3))),
                check=lambda got, args: np.isinf(args[-1]).any() and (args[-1][:, 1] == args[7]).any())


@case("prognosis.drift_prognosis")
def _(rng: np.random.Generator) -> Case:
    n, d = 200, 3
    value, drift, v_tt, v_td, v_dd = (x.reshape(n, d) for x in drift_case(rng, n * d))
    stamps = np.repeat(rng.uniform(0.0, 500.0, n)[:, None], d, axis=1)
    lower, upper = np.array([90.0, 80.0, 95.0]), np.array([110.0, 120.0, 105.0])
    return Case((value, drift, v_tt, v_td, v_dd, stamps, rng.integers(1, d + 1, n), rng.random(n) < 0.6, lower, upper,
                 rng.uniform(0.0, 0.05, d), stamps[:, 0] + 0.5, Z2, 300.0, np.empty((7, n))),
                check=lambda got, args: np.isinf(args[-1][1]).any() and np.isfinite(args[-1][1]).any())


@case("detection.detect")
def _(rng: np.random.Generator) -> Case:
    n, elements, subs, balances = 40, 5, 120, 60
    ea = rng.uniform(0.0, 2.0, (n, elements, subs))
    ea_reference = ea * rng.normal(1.0, 0.05, ea.shape)
    ea_reference[3] = 0.0  # a system at rest: the denominators' floor
    span = np.append(np.full(elements, 500), 6000)
    alarm = rng.random(n) < 0.3
    return Case((5, 37, ea, ea_reference, 50, rng.normal(0.0, 0.01, (n, balances)), rng.uniform(0.0, 1.0, (n, balances)),
                 rng.integers(0, 80, n), 100, span, rng.uniform(0.01, 0.1, elements + 1), 3, rng.uniform(0.0, 100.0, n), TINY,
                 rng.integers(0, 4, n), alarm, np.where(alarm, 1.0, np.nan), np.zeros((n, elements + 1))),
                check=lambda got, args: args[15].sum() > alarm.sum() and (args[14][5:37] == 0).any())


def histories(rng: np.random.Generator, n: int, widths: tuple[int, ...], lengths: np.ndarray) -> tuple[np.ndarray, ...]:
    return tuple(rng.standard_normal((n, a, 2 * length)) for a, length in zip(widths, lengths, strict=True))


@case("history.slide")
def _(rng: np.random.Generator) -> Case:
    return Case((rng.standard_normal((2, 3, 20)), 8, 10, 4), check=lambda got, args: got == 0)  # past the end: back to 0


@case("history.record_step")
def _(rng: np.random.Generator) -> Case:
    n, elements, subs, components, windows, nx = 3, 4, 5, 2, 3, 2
    lengths = np.array([10, 10, 4, 4, 4, 4, 4, 4])
    widths = (elements, elements, components * components, components, 1, 1, 1, 2 * nx)
    return Case((rng.standard_normal((n, elements, subs)), rng.standard_normal((n, elements, subs)),
                 rng.standard_normal((n, windows, components, components)), rng.standard_normal((n, windows, components)),
                 rng.standard_normal((n, windows)), rng.standard_normal((n, 2, nx)), np.array([1, 3]), 0.5, rng.uniform(0, 9, n),
                 rng.integers(0, 9, n), histories(rng, n, widths, lengths), np.array([8, 9, 1, 4, 0, 0, 3, 2]), lengths),
                check=lambda got, args: args[11][0] == 0 and args[11][2] == 2)


# --- multisine, propagation, expm ---------------------------------------------------------------------


@case("multisine.multisine_rotations")
def _(rng: np.random.Generator) -> Case:
    return Case((rng.uniform(0.1, 5.0, (3, 7)), H), rtol=0.0, atol=1e-15)


def multisine_case(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n, components, samples = 70, 9, 400  # more systems than one block, more samples than one rotation span
    t = rng.uniform(0.0, 10.0, (n, 1)) + H * np.arange(samples)
    return t, rng.uniform(0.0, 2 * np.pi, (n, components)), multisine_rotations(rng.uniform(0.1, 5.0, (n, components)), H)


@case("multisine.rotated_multisine")
def _(rng: np.random.Generator) -> Case:
    return Case(multisine_case(rng), rtol=0.0, atol=1e-9)


@case("multisine.rotated_multisine_into")
def _(rng: np.random.Generator) -> Case:
    t, phases, rotation = multisine_case(rng)
    return Case((t, phases, rotation, rng.standard_normal(len(t)), rng.uniform(0.5, 2, len(t)), np.empty(t.shape), np.empty(t.shape)),
                rtol=0.0, atol=1e-9)


@case("propagation.propagate_states")
def _(rng: np.random.Generator) -> Case:
    n, steps, nx, m = 3, 20, 4, 8
    return Case((0.3 * rng.standard_normal((n, steps, nx, nx)), rng.standard_normal((n, steps, nx, m)), rng.standard_normal((n, steps, m)),
                 rng.standard_normal((n, nx))), rtol=1e-12, atol=1e-12)


@case("propagation.simulate_hermite")
def _(rng: np.random.Generator) -> Case:
    n, samples, nx, nu, distinct = 130, 40, 3, 2, 4  # more systems than one block, more samples than one chunk
    u, du = rng.standard_normal((2, 5, samples, nu))
    return Case((0.3 * rng.standard_normal((distinct, nx, nx)), 0.1 * rng.standard_normal((distinct, nx, 4 * nu)), rng.integers(0, distinct, n),
                 u, du, rng.integers(0, 5, n), H, rng.standard_normal((n, nx)), rng.uniform(0.5, 2.0, (n, nx)), np.empty((n, nx, samples)),
                 np.empty((n, nx))), rtol=1e-10, atol=1e-11)


@case("expm.matmul")
def _(rng: np.random.Generator) -> Case:
    return Case((*rng.standard_normal((2, 6, 6)), np.empty((6, 6))), rtol=1e-13, atol=1e-13)


@case("expm.solve")
def _(rng: np.random.Generator) -> Case:
    a, b = rng.standard_normal((2, 6, 6))
    return Case((a + 6 * np.eye(6), b), rtol=1e-10, atol=1e-10, workspaces=(0,))


@case("expm.pade_polynomial")
def _(rng: np.random.Generator) -> Case:
    A2, A4, A6 = rng.standard_normal((3, 4, 4)) * 0.1
    return Case((A2, A4, A6, PADE13[0::2], np.empty((4, 4)), np.empty((4, 4))), rtol=1e-13, atol=1e-3, workspaces=(4,))


@case("expm.expm_batch")
def _(rng: np.random.Generator) -> Case:
    Z = rng.standard_normal((3, 6, 6))
    Z *= np.array([0.01, 1.0, 40.0])[:, None, None] / np.abs(Z).sum(axis=1).max(axis=1)[:, None, None]  # scaled and squared where large
    return Case((Z, np.empty_like(Z)), rtol=1e-11, atol=1e-13)


@case("expm.held_input_discretization")
def _(rng: np.random.Generator) -> Case:
    nx, nu, size = 3, 1, 8
    chain = np.zeros((size - nx, size))
    chain[np.arange(size - nx - 1), nx + 1 + np.arange(size - nx - 1)] = 1.0  # each input derivative drives the one before
    return Case((rng.standard_normal((4, nx, nx)), rng.standard_normal((4, nx, nu)), H, chain, np.empty((4, nx, nx)), np.empty((4, nx, size - nx))),
                rtol=1e-11, atol=1e-14)


# --- smoothing and the monitor -------------------------------------------------------------------------

FILTER = SavitzkyGolay(11, 3, H)
SMOOTHING = Smoothing(FILTER.moments(), FILTER.lane_coefficients(0), FILTER.lane_coefficients(1))
SMOOTH_TOLERANCE = {"rtol": 1e-9, "atol": 1e-9}  # running moments against direct sums, signals of ~10


@case("smoothing.filter_into")
def _(rng: np.random.Generator) -> Case:
    return Case((rng.standard_normal(160).cumsum(), np.empty(160), *FILTER.coefficients(1)), **SMOOTH_TOLERANCE)


@case("smoothing.filter_rows")
def _(rng: np.random.Generator) -> Case:
    return Case((rng.standard_normal((5, 160)).cumsum(-1), *FILTER.coefficients(0)), **SMOOTH_TOLERANCE)


@case("smoothing.filter_lanes")
def _(rng: np.random.Generator) -> Case:
    x = rng.standard_normal((60, LANES)).cumsum(0)
    return Case((x, 3, *SMOOTHING, True, np.zeros_like(x), np.zeros_like(x)), **SMOOTH_TOLERANCE)


@case("monitor.copy")
def _(rng: np.random.Generator) -> Case:
    return Case((np.arange(10.0), 7, np.zeros(6), 2))


@case("monitor.same")
def _(rng: np.random.Generator) -> Case:
    return Case((np.array([9.0, 1, 2]), np.array([5.0, 1, 2]), 1), check=lambda got, args: got)


def rows_with_shared_loads(rng: np.random.Generator, M: int, channels: int, T: int) -> np.ndarray:
    rows = rng.standard_normal((M, channels, T)).cumsum(-1)
    rows[1, -1, 1:] = rows[0, -1, 1:]  # the predecessor's load from sample 1 on
    rows[M // 2 + 2, -1] = rows[2, -1]  # its twin's
    return rows


@case("monitor.load_sources")
def _(rng: np.random.Generator) -> Case:
    return Case((rows_with_shared_loads(rng, 6, 3, 12), 2, 1), check=lambda got, args: list(got[0]) == [0, 0, 2, 3, 4, 2])


@case("monitor.smooth_rows")
def _(rng: np.random.Generator) -> Case:
    M, channels, T, skip, cut = 6, 3, 60, 4, 5
    length = T - skip - cut
    inertia = np.array([[1.0, 0.0, 2.0]])  # channel 1 is an I element's flow
    return Case((rows_with_shared_loads(rng, M, channels, T), skip, cut, SMOOTHING, inertia, np.empty((M, channels, length)),
                 np.empty((M, 1, length))), **SMOOTH_TOLERANCE)


def nominal_laws(rng: np.random.Generator, nx: int) -> NominalLaws:
    bonds = 8
    return NominalLaws(rng.uniform(0.5, 2.0, nx), rng.standard_normal((bonds, nx)), rng.standard_normal(bonds), rng.standard_normal(bonds),
                       np.array([0, 1, 2]), np.array([4, 5, 6]), np.array([1.0, -1.0, 1.0]), np.array([[1.0, 2.0, 3.0]]))


@case("monitor.element_powers")
def _(rng: np.random.Generator) -> Case:
    M, nx, L = 3, 2, 30
    return Case((rng.standard_normal((M, nx + 1, L)), rng.standard_normal((M, 1, L)), nominal_laws(rng, nx), np.empty((M, 3, L))))


WINDOWS = EnergyWindows(H, 5, 2, np.array([1, 2, 3]), np.array([0]))
INERTIA = np.array([[0.0, 2.0, 1.5]])


def chunk_input(rng: np.random.Generator, n: int = 2, E: int = 4, nx: int = 2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    T = 5 * 2 * 3 + 1
    return rng.standard_normal((2 * n, E, T)), rng.standard_normal((2 * n, nx + 1, T)), rng.standard_normal((n, nx, T - 1))


@case("monitor.sub_window_energies")
def _(rng: np.random.Generator) -> Case:
    power, smooth, _ = chunk_input(rng)
    power[0, 0, 3] = np.nan  # not finite
    return Case((power, smooth, H, 5, INERTIA), check=lambda got, args: not got[0])


@case("monitor.energy_balances")
def _(rng: np.random.Generator) -> Case:
    return Case((rng.standard_normal((4, 4, 6)), WINDOWS.components, WINDOWS.sources))


@case("monitor.balance_statistics")
def _(rng: np.random.Generator) -> Case:
    return Case((rng.standard_normal((4, 4, 6)), rng.standard_normal((4, 6)), WINDOWS.components, 2))


@case("monitor.noise_sums")
def _(rng: np.random.Generator) -> Case:
    return Case((rng.standard_normal((2, 2, 30)), rng.standard_normal((4, 3, 31))))


@case("monitor.chunk_statistics")
def _(rng: np.random.Generator) -> Case:
    return Case((*chunk_input(rng), WINDOWS, INERTIA), check=lambda got, args: got[0])


def chunk_context(rng: np.random.Generator, n: int, nx: int) -> np.ndarray:
    context = np.full((2 * n, nx + 1, FILTER.half), np.nan)  # fresh systems: their chunk mirrored
    context[1] = 7.0  # system 1's real rows carry context from a previous chunk
    context[n + 2] = rng.standard_normal((nx + 1, FILTER.half))
    return context


@case("monitor.padded_chunk")
def _(rng: np.random.Generator) -> Case:
    n, nx, T = 4, 2, 12
    return Case((rng.standard_normal((n, nx, T)), rng.standard_normal((n, nx, T)), rng.standard_normal((n, T)), chunk_context(rng, n, nx), 1, 3,
                 np.empty((4, nx + 1, FILTER.half + T))))


@case("monitor.monitor_chunk_step")
def _(rng: np.random.Generator) -> Case:
    n, nx, T = 20, 2, 31  # more systems than one block of LANES
    windows = EnergyWindows(H, 5, 2, np.array([1, 2]), np.array([0]))
    signals = ChunkSignals(rng.standard_normal((n, nx, T)).cumsum(-1), rng.standard_normal((n, nx, T)).cumsum(-1), rng.standard_normal((n, T)))
    outputs = ChunkOutputs(np.zeros((2 * n, 3, 6)), np.zeros((n, 3)), np.zeros((n, 3, 2, 2)), np.zeros((n, 3, 2)), np.zeros((n, 2, nx)),
                           np.zeros((n, nx, T)))
    return Case((1, 19, signals, chunk_context(rng, n, nx), SMOOTHING, nominal_laws(rng, nx), windows, outputs), rtol=1e-6, atol=1e-7,
                check=lambda got, args: got)


# --- tracking ------------------------------------------------------------------------------------------

NX, NW = 2, 4


def filter_bank(rng: np.random.Generator) -> FilterBank:
    """Three hypotheses: "none" (one term, no process noise: the kernel's fixed-parameter blocks), one read
    through 1 / theta on state 1, one that is not."""
    coefficients = np.zeros((3, 4, NX, NX + NW))
    coefficients[:, 0, :, :NX] = [[0.99, 0.01], [-0.02, 0.98]]
    coefficients[:, 0, :, NX:] = 1e-3 * rng.standard_normal((3, NX, NW))
    coefficients[1:, 1:] = 1e-3 * rng.standard_normal((2, 3, NX, NX + NW))
    nominal = np.array([1.0, 2.0, 0.5])
    gain = np.ones((3, NX))
    gain[1, 1] = 1.0 / nominal[1]
    process_noise = np.array([[0.0, 0.0], [1e-6, 1e-9], [1e-6, 1e-9]])
    prior = np.array([[0.0, 0.0], [1e-2, 1e-4], [1e-3, 1e-5]])
    hypotheses = HypothesisModels(coefficients, np.array([1, 4, 3]), 0.5 * nominal, 1.5 * nominal, gain, np.array([-1, 1, -1]), nominal)
    return FilterBank(hypotheses, process_noise, prior)


SETTINGS = FilterSettings(1e-3, 0.99, H, 1e-4)


def tracked_signals(rng: np.random.Generator, n: int, samples: int = 21) -> TrackedSignals:
    t = H * np.arange(samples)
    phase = rng.uniform(0, 2 * np.pi, (n, 1, 1))
    measured = np.sin(2 * np.pi * np.array([1.0, 1.3])[None, :, None] * t + phase) * (1 + 0.01 * rng.standard_normal((n, NX, samples)))
    load, load_rate = np.sin(5 * t + phase[:, 0]), 5 * np.cos(5 * t + phase[:, 0])
    return TrackedSignals(measured, load, load_rate, np.array([1.0, 2.0, 5.0])[:n])


def running_filters(rng: np.random.Generator, bank: FilterBank, n: int) -> FilterStates:
    z = np.zeros((n, 3, NX + 2))
    z[..., :NX] = rng.standard_normal((n, 3, NX))
    z[..., NX] = bank.hypotheses.nominal * np.array([1.0, 1.03, 0.98])  # off nominal, so that every theta-slope matters
    z[:, 1:, NX + 1] = 1e-3
    P = np.zeros((n, 3, NX + 2, NX + 2))
    P[..., np.arange(NX), np.arange(NX)] = 1e-4
    P[:, 1:, NX, NX], P[:, 1:, NX + 1, NX + 1] = 1e-3, 1e-6
    return FilterStates(np.array([False, True, True])[:n], np.array([0.0, 1.8, 0.2])[:n], z, P, rng.standard_normal((n, 3)), np.full((n, 3), 9.0))


TRACKING_TOLERANCE = {"rtol": 1e-7, "atol": 1e-10}  # the filter bank's lanes sum in another order


@case("tracking.track_step")
def _(rng: np.random.Generator) -> Case:
    bank = filter_bank(rng)
    outputs = TrackOutputs(np.zeros((6, 3, 2)), np.zeros((3, 3)))
    # system 0 starts, system 1 runs on, system 2's step stands for more time than its signals (carried)
    return Case((bank, SETTINGS, 0, 3, tracked_signals(rng, 3), running_filters(rng, bank, 3), outputs, (0.0,) * NX, (0.0,) * NW),
                **TRACKING_TOLERANCE, check=lambda got, args: args[5].started.all())


@case("tracking.track_filters")
def _(rng: np.random.Generator) -> Case:
    bank = filter_bank(rng)
    variance = rng.uniform(1e-6, 1e-4, (2, NX))
    return Case((bank, SETTINGS, np.array([H, 0.0]), 1, tracked_signals(rng, 3), variance, running_filters(rng, bank, 3), (0.0,) * NX, (0.0,) * NW),
                **TRACKING_TOLERANCE, check=step_nis_written)


def step_nis_written(got: object, args: tuple) -> None:
    """``track_filters``' normalized innovations squared: the step's sum for systems 1 and 2, positive; system 0's untouched."""
    nis = args[6].nis
    np.testing.assert_array_equal(nis[0], 9.0)
    assert (nis[1:] > 0).all() and (nis[1:] != 9.0).all()


@case("tracking.chebyshev_matrices")
def _(rng: np.random.Generator) -> Case:
    coefficients = rng.standard_normal((5, 2, 3))
    theta = 3.4  # past hi: the nearer end's
    return Case((coefficients, 4, 1.0, 3.0, theta, np.empty((2, 3)), np.empty((2, 3)), np.empty((2, 5))), rtol=1e-13, atol=1e-13, workspaces=(7,))


@case("tracking.hermite_row")
def _(rng: np.random.Generator) -> Case:
    return Case((*rng.standard_normal(4), H))


@case("tracking.measurement_variance")
def _(rng: np.random.Generator) -> Case:
    measured = rng.standard_normal((3, 200))
    measured[2] = 0.0  # a channel at rest: the floor
    return Case((measured, 1e-4, np.empty(200), summation_scratch(), np.empty(3)), workspaces=(2, 3))


@case("tracking.start_filters")
def _(rng: np.random.Generator) -> Case:
    bank = filter_bank(rng)
    hypotheses = bank.hypotheses
    return Case((rng.standard_normal(NX), rng.uniform(1e-6, 1e-4, NX), hypotheses.gain, hypotheses.nominal, bank.prior, np.full((3, NX + 2), 9.0),
                 np.full((3, NX + 2, NX + 2), 9.0), np.full(3, 9.0)))


@case("tracking.carry_filters")
def _(rng: np.random.Generator) -> Case:
    bank = filter_bank(rng)
    filters = running_filters(rng, bank, 1)
    filters.z[0, 2, NX + 1] = 1.0  # drifts past its upper limit: held there
    return Case((3.0, bank.hypotheses.lo, bank.hypotheses.hi, bank.process_noise, H, filters.z[0], filters.P[0]),
                check=lambda got, args: args[5][2, NX] == args[2][2])


# --- isolation -----------------------------------------------------------------------------------------


def regressions(rng: np.random.Generator, n: int, components: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sums of n regressions, some rank-deficient (a component never excited) or nearly collinear."""
    energies = rng.normal(size=(n, components, 40)) * 10.0 ** rng.uniform(-3, 3, (n, components, 1))
    energies[: n // 4, rng.integers(components)] = 0.0
    energies[n // 4 : n // 3, 1] = 1e-9 * energies[n // 4 : n // 3, 0]
    residual = np.einsum("nct,nc->nt", energies, rng.normal(size=(n, components)) * 0.01) + rng.normal(size=(n, 40))
    return energies @ energies.transpose(0, 2, 1), np.einsum("nct,nt->nc", energies, residual), (residual**2).sum(-1)


@case("isolation.history_sums")
def _(rng: np.random.Generator) -> Case:
    gram, cross, other = rng.normal(size=(6, 3, 3, 40))[..., 7:27], rng.normal(size=(6, 3, 40))[..., 13:33], rng.normal(size=(6, 4, 30))[..., 5:25]
    return Case((gram, cross, other, np.array([5, 0, 3]), 10, True))


@case("isolation.pseudo_inverse_factors")
def _(rng: np.random.Generator) -> Case:
    gram, _, _ = regressions(rng, 50)
    gram[0] = 2.0 * np.eye(3)  # tied magnitudes
    return Case((*np.linalg.eigh(gram), 1e-12), check=lambda got, args: got[2])


@case("isolation.chi_squares")
def _(rng: np.random.Generator) -> Case:
    gram, cross, square = regressions(rng, 200, 4)
    inverse = np.linalg.pinv(gram, rcond=1e-12, hermitian=True)
    return Case((gram, cross, square, rng.integers(1, 60, 200), inverse, np.array([2, -1, 0, 1, 3])))


@case("isolation.balance_log_ratios")
def _(rng: np.random.Generator) -> Case:
    gram, cross, square = regressions(rng, 30)
    square[:2] = np.nan  # NaN chi-squares propagate through the smallest
    inverse = np.linalg.pinv(gram, rcond=1e-12, hermitian=True)
    return Case((gram, cross, square, inverse, rng.integers(0, 60, 50), rng.permutation(50)[:30], 25, 3, np.array([2, -1, 0, 1]), 2.7, 50))


@case("isolation.suspect_hypotheses")
def _(rng: np.random.Generator) -> Case:
    return Case((np.array([False, True, True, False, True]), np.array([2, 1, 3, 0, 2]), 3))


@case("isolation.network_average")
def _(rng: np.random.Generator) -> Case:
    return Case((rng.random((3, 4)), np.array([6, 1, 2]), 7, 0.3, rng.random((7, 4))))


def beliefs(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    average = rng.dirichlet(np.ones(4), n) * rng.uniform(0, 2, (n, 1))
    average[:10] = 0.0  # before the network's first frame
    log_evidence = rng.normal(0, 30, (n, 4))
    log_evidence[rng.uniform(size=(n, 4)) < 0.2] = np.nan  # hypotheses not fitted yet
    log_evidence[10:15] = np.nan
    log_evidence[15:20, 2] = -np.inf
    return average, log_evidence, rng.uniform(size=n) < 0.8


@case("isolation.belief_inputs")
def _(rng: np.random.Generator) -> Case:
    return Case((*beliefs(rng, 60), 0.7, 1e-3), check=lambda got, args: not got[2].all() and got[2].any())


@case("isolation.shifted_log_belief")
def _(rng: np.random.Generator) -> Case:
    return Case((np.log(rng.random((40, 4))), rng.normal(0, 5, (40, 4)), -rng.exponential(5.0, (40, 4)), 0.8, 0.5))


@case("isolation.verdict")
def _(rng: np.random.Generator) -> Case:
    n = 80
    belief = rng.random((n, 4))
    belief[5, 1:] = belief[5, 1]  # equal fault classes: the first
    return Case((belief, rng.random(n) < 0.8, rng.integers(0, 4, n), np.zeros(n, dtype=bool), rng.random((n, 3)) < 0.5, 0.5),
                check=lambda got, args: len(got[4]) > 0 and got[3].any() and (~got[3] & (got[1] > 0)).any())


# --- observation, features, network --------------------------------------------------------------------


@case("observation.observation_rows")
def _(rng: np.random.Generator) -> Case:
    n, E, C, K, P = 12, 4, 3, 4, 3
    ea = rng.uniform(-1, 30, (n, E))
    ea[0, 0] = np.nan  # kept, clipped as np.clip keeps it
    rul = rng.uniform(-5, 500, (n, 3))
    rul[1] = np.nan  # read as rul_max
    values = rng.uniform(-1, 3, (n, P))
    return Case((ea, rng.uniform(0, 20, (n, E)), rng.random((n, C)), rng.uniform(0, 900, n), rng.integers(0, 2, n), rng.random((n, K)), values,
                 np.zeros(P), np.full(P, 2.0), rul, 300.0, 600.0, 1e-3, -0.5, 1.5, 25.0, np.zeros((n, 2 * E + C + 2 + K + P + 3), dtype=np.float32)))


def frame(rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    n, E, F, C = 5, 4, 20, 3
    ea = rng.uniform(0, 2, (n, E, 2 * F))[..., 3 : 3 + F]  # a window on a longer history
    ea_reference = ea * rng.normal(1, 0.05, ea.shape)
    ea_reference[2] = 0.0  # at rest: the floor
    gram, cross, _ = regressions(rng, n, C)
    return ea, ea_reference, gram, cross


@case("features.frame_sums")
def _(rng: np.random.Generator) -> Case:
    ea, ea_reference, gram, cross = frame(rng)
    rows, F, E, C, X = np.array([4, 0, 2]), ea.shape[2], ea.shape[1], 3, 2
    return Case((ea, ea_reference, gram, cross, rng.random((5, X)), rows, 1, np.array([1, 2, 3]), np.hanning(F), 1e-6, np.zeros((3, F)),
                 np.zeros((3, 3 * E + 2 * C + X)), np.zeros(3), np.zeros((3, C, C)), np.zeros((3, C, 1))))


@case("features.relative_noise")
def _(rng: np.random.Generator) -> Case:
    noise = rng.random((4, 2, 3))
    noise[0, 1] = 0.0  # no signal: the floor
    return Case((noise,))


def spectra(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    magnitude = rng.random((6, 40))
    magnitude[1, 10:12] = 0.5  # a plateau: tied
    magnitude[2, [5, 20]] = 3.0  # equal peaks: tied
    magnitude[3] = np.linspace(0, 1, 40)  # no peak
    return magnitude, np.linspace(0, 50, 40)


@case("features.spectrum_peaks")
def _(rng: np.random.Generator) -> Case:
    return Case((*spectra(rng), 40.0, 0.3, np.empty((6, 6))), check=lambda got, args: got[1] and got[2] and (args[4][3] == 0).all())


@case("features.peak_and_deviation_features")
def _(rng: np.random.Generator) -> Case:
    magnitude, frequencies = spectra(rng)
    scale = rng.random(6)
    scale[0] = 0.0
    return Case((magnitude, scale, frequencies, 40.0, 0.3, rng.normal(0, 3, (6, 3, 1)), 2.0, np.zeros((6, 12)), 1, 5))


@case("network.mlp_probabilities")
def _(rng: np.random.Generator) -> Case:
    inputs = rng.standard_normal((9, 5))
    inputs[3, 2] = np.inf  # not finite: reported
    weights = (rng.standard_normal((5, 8)), rng.standard_normal((8, 4)))
    return Case((inputs, rng.standard_normal(5), rng.uniform(0.5, 2, 5), weights, (rng.standard_normal(8), rng.standard_normal(4)),
                 np.empty((9, 4))), rtol=1e-13, atol=1e-15, check=lambda got, args: not got)
