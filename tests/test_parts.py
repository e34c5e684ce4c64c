"""Every part's health (``PartHealth``): the joint filter beside the chain's estimator, each part named degrading
or not and its own End of Life, on records an independent ODE made (``tests/ode_records.py``: solve_ivp, 1 %
sensor noise, a multisine load).

Set isolation (two and three parts ramping, overlapping onsets, different rates; the test's seeds, not the 0-4
the joint filter's settings were chosen on: 10 for the spring-mass-damper, whose two-part case sits near the
target, 5 for the others): from 30 s after each part's onset, the set of parts named equals the set degrading in
these fractions of the steps, and each degrading part's 95 % RUL interval covers the truth in these fractions
of its named steps:

====================  =======================  ===============================================
system (seeds)        set exact, two / three    RUL coverage per part, two / three
====================  =======================  ===============================================
spring_mass_damper    0.958 / 0.984             k 1.0, b 0.972 / m 0.997, k 1.0, b 0.959
(10-19)
rlc_circuit (10-14)   1.0 / 1.0                 R1 0.998, C1 0.994 / L1 0.995, R2 0.988, R1 0.991
dc_motor (10-14)      1.0 / 1.0                 Ra 1.0, bm 1.0 / J 0.996, K 1.0, Ra 0.998
====================  =======================  ===============================================
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import gymnasium as gym
import numpy as np
import pytest
from ode_records import Fault, chain_for, run_chain, simulate

import ea_gym  # noqa: F401  (registers the environments)
from ea_gym.models import get_model, spring_mass_damper
from ea_gym.phm import (
    DriftPrognosis,
    ExtrapolationConfig,
    HealthStatus,
    JointFilter,
    ParameterEstimates,
    PartHealth,
    chain_config,
    drift_end_of_life,
)

MODEL = spring_mass_damper()
SETTLE = 30.0  # s after a part's onset from which its naming counts
DURATION = 150.0  # s
SEEDS = {"spring_mass_damper": tuple(range(10, 20)), "rlc_circuit": tuple(range(10, 15)), "dc_motor": tuple(range(10, 15))}

#: (parameter, onset s, rate as a fraction of its safe span per s): two and three parts, overlapping, different rates,
#: each at least twice ``JointFilterConfig.degrading_rate`` (the environment's slowest wear, 0.5 % of the way to a
#: limit per s, is 3-4e-3 of the span per s)
SCENARIOS = {
    "spring_mass_damper": {"two": (("k", 20, -3e-3), ("b", 40, 5e-3)), "three": (("m", 20, 4e-3), ("k", 35, -3e-3), ("b", 50, 6e-3))},
    "rlc_circuit": {"two": (("R1", 20, 3e-3), ("C1", 40, -4e-3)), "three": (("L1", 20, 4e-3), ("R2", 35, -3e-3), ("R1", 50, 5e-3))},
    "dc_motor": {"two": (("Ra", 20, 3e-3), ("bm", 40, 4e-3)), "three": (("J", 20, 4e-3), ("K", 35, -4e-3), ("Ra", 50, 3e-3))},
}


def faults_of(system: str, kind: str) -> tuple[Fault, ...]:
    model = get_model(system)
    spans = {name: high - low for name, (low, high) in model.safe_limits.items()}
    return tuple(Fault(name, onset, rate * spans[name]) for name, onset, rate in SCENARIOS[system][kind])


@dataclass(frozen=True)
class SetRun:
    """The chain's parts over records of one scenario: times (S,), named (S, N, D), eol_low and eol_high (S, N, D)."""

    names: tuple[str, ...]
    t: np.ndarray
    named: np.ndarray
    eol_low: np.ndarray
    eol_high: np.ndarray


def set_run(system: str, kind: str, seeds: Sequence[int] | None = None) -> tuple[SetRun, tuple[Fault, ...]]:
    """The chain over ``system``'s records of scenario ``kind`` (``SCENARIOS``), one machine per seed (default ``SEEDS``)."""
    faults = faults_of(system, kind)
    seeds = SEEDS[system] if seeds is None else seeds
    records = [simulate(system, seed, DURATION, faults) for seed in seeds]
    chain = chain_for(system, len(records))
    statuses = run_chain(chain, records)
    parts = [status.parts for status in statuses]
    assert all(p is not None for p in parts)
    return SetRun(
        names=chain.degradable, t=np.array([s.t[0] for s in statuses]), named=np.array([p.named for p in parts if p is not None]),
        eol_low=np.array([p.eol_low for p in parts if p is not None]), eol_high=np.array([p.eol_high for p in parts if p is not None]),
    ), faults


def set_exact(run: SetRun, faults: Sequence[Fault]) -> float:
    """The fraction of (step, machine) from the first onset + ``SETTLE`` whose named set is the degrading set, each part
    counted from its own onset + ``SETTLE`` (named or not, either is right before)."""
    onsets = {fault.name: fault.onset for fault in faults}
    degrading = np.array([[name in onsets and t >= onsets[name] for name in run.names] for t in run.t])  # (S, D)
    settling = np.array([[name in onsets and onsets[name] <= t < onsets[name] + SETTLE for name in run.names] for t in run.t])
    right = np.all((run.named == degrading[:, None]) | settling[:, None], axis=2)  # (S, N)
    return float(right[run.t >= min(onsets.values()) + SETTLE].mean())


def coverage(run: SetRun, fault: Fault, model_name: str) -> float:
    """The fraction of the steps where ``fault``'s part is named (before it reaches its limit) whose RUL interval holds its true End of Life."""
    low, high = get_model(model_name).safe_limits[fault.name]
    nominal = get_model(model_name).nominal[fault.name]
    true_eol = fault.onset + ((high if fault.slope > 0 else low) - nominal) / fault.slope
    d = run.names.index(fault.name)
    named = run.named[..., d] & (run.t[:, None] < true_eol)
    covered = (run.eol_low[..., d] <= true_eol) & (true_eol <= run.eol_high[..., d])
    return float(covered[named].mean())


@pytest.mark.parametrize("system", ["spring_mass_damper", "rlc_circuit", "dc_motor"])
@pytest.mark.parametrize("kind", ["two", "three"])
def test_the_set_of_degrading_parts_is_named_and_each_part_gets_its_own_end_of_life(system: str, kind: str) -> None:
    run, faults = set_run(system, kind)
    # issue 30's acceptance: the set named exactly in >= 95 % of the steps from onset + 30 s
    assert set_exact(run, faults) >= 0.95
    for fault in faults:
        # and each degrading part's 95 % RUL interval covering the truth in >= 90 % of its named steps
        assert coverage(run, fault, system) >= 0.9, fault.name
    # a part that never degrades is named in no step past the first onset's settling
    constant = [d for d, name in enumerate(run.names) if name not in {f.name for f in faults}]
    settled = run.t >= min(f.onset for f in faults) + SETTLE
    assert not constant or run.named[settled][..., constant].mean() < 0.02


def test_rul_and_machine_rul_read_every_part_and_the_soonest() -> None:
    inf = math.inf
    parts = PartHealth(
        names=("k", "m", "b"), t=np.array([10.0, 20.0]), value=np.ones((2, 3)), std=np.ones((2, 3)), degrading=np.zeros((2, 3)),
        named=np.array([[True, True, False], [False, False, False]]),
        eol=np.array([[50.0, 30.0, inf], [inf, inf, inf]]), eol_low=np.array([[40.0, 25.0, inf], [inf, inf, inf]]),
        eol_high=np.array([[70.0, 45.0, inf], [inf, inf, inf]]),
    )
    np.testing.assert_array_equal(parts.rul[0], [[40.0, 30.0, 60.0], [20.0, 15.0, 35.0], [inf, inf, inf]])
    assert parts.rul.shape == (2, 3, 3) and np.all(np.isinf(parts.rul[1]))
    np.testing.assert_array_equal(parts.machine_rul, [[20.0, 15.0, 35.0], [inf, inf, inf]])


def estimates(value: np.ndarray, drift: np.ndarray, t: float) -> ParameterEstimates:
    """Certain values and drifts (N, D) at time ``t``: zero (co)variances."""
    zeros = np.zeros_like(value)
    return ParameterEstimates(
        value=value, variance=zeros, drift=drift, drift_variance=zeros, covariance=zeros, log_evidence=np.zeros((len(value), value.shape[1] + 1)),
        estimated=np.ones(value.shape, dtype=bool), time=np.full(value.shape, t), degrading=np.ones(value.shape),
    )


def test_every_named_part_is_carried_to_its_own_limit() -> None:
    names = ("k", "m", "b")
    prognosis = DriftPrognosis(MODEL, names, ExtrapolationConfig(horizon=1000.0), np.zeros(3), 2)
    # system 0: k at 95 N/m falling 0.5 N/m/s (85 N/m in 20 s), m at 10 kg rising 0.01 kg/s (11 kg in 100 s), b
    # steady; system 1: k falling 0.005 N/m/s (2000 s: beyond the horizon), m rising as system 0's but not named
    value = np.array([[95.0, 10.0, 0.5], [95.0, 10.0, 0.5]])
    drift = np.array([[-0.5, 0.01, 0.0], [-0.005, 0.01, 0.0]])
    named = np.array([[True, True, True], [True, False, False]])
    eol, low, high = prognosis.every_part(estimates(value, drift, 10.0), named)
    np.testing.assert_allclose(eol[0, :2], [30.0, 110.0])
    np.testing.assert_array_equal(low[0, :2], eol[0, :2])  # certain: the interval is the point
    np.testing.assert_array_equal(high[0, :2], eol[0, :2])
    assert np.isinf(eol[0, 2]) and np.all(np.isinf([eol[1], low[1], high[1]]))
    # with uncertainty, the same function as the single suspect's prognosis, element by element
    record = dataclasses.replace(estimates(value, drift, 10.0), variance=np.full((2, 3), 0.01), drift_variance=np.full((2, 3), 1e-6))
    eol, low, high = prognosis.every_part(record, np.ones((2, 3), dtype=bool))
    covariance = np.array([[0.01, 0.0], [0.0, 1e-6]])
    for d, name in enumerate(names):
        expected = drift_end_of_life(value[0, d], drift[0, d], covariance, np.array(MODEL.safe_limits[name]), 10.0, 0.95)
        np.testing.assert_array_equal([eol[0, d], low[0, d], high[0, d]], [np.where(e - 10.0 > 1000.0, np.inf, e) for e in expected])


def test_the_joint_filter_runs_beside_the_chosen_estimator_and_is_the_estimator_when_chosen() -> None:
    beside = chain_for("spring_mass_damper", 1)
    assert isinstance(beside.joint, JointFilter) and beside.joint is not beside.estimator
    assert beside.innovations is beside.joint  # the model-fit test reads the filter that explains every part
    config = chain_config(100.0, 0.01)
    own = chain_for("spring_mass_damper", 1, dataclasses.replace(config, estimator_kind="joint"))
    assert own.joint is own.estimator  # not two filters
    off = chain_for("spring_mass_damper", 1, dataclasses.replace(config, joint=dataclasses.replace(config.joint, beside=False)))
    assert off.joint is None and off.innovations is off.estimator
    record = simulate("spring_mass_damper", 3, 12.0)
    for chain, expect_parts in ((beside, True), (own, True), (off, False)):
        status: HealthStatus = run_chain(chain, [record])[-1]
        assert (status.parts is not None) == expect_parts
        if status.parts is not None:
            assert status.parts.names == chain.degradable and status.parts.value.shape == (1, 3)
            np.testing.assert_allclose(status.parts.value[0], MODEL.parameter_vector()[[MODEL.parameter_names.index(n) for n in chain.degradable]],
                                       rtol=0.02)
    # the v0 environments run without it: their episodes stay as they were
    env = gym.make("ea_gym/SpringMassDamper-v0")
    assert env.unwrapped.core.chain.joint is None
    env.close()


def test_no_part_is_named_and_no_end_of_life_given_while_the_model_does_not_fit() -> None:
    """A ramp of k read with the load in kN as if it were N: the joint filter explains it with parts far off and
    drifting, the model-fit test says the model does not fit, and no part is named."""
    record = simulate("spring_mass_damper", 4, 60.0, (Fault("k", 5.0, -0.1),))
    misread = dataclasses.replace(record, load=record.load / 1000.0, load_rate=record.load_rate / 1000.0)
    statuses = run_chain(chain_for("spring_mass_damper", 1), [misread])
    parts = [s.parts for s in statuses if s.parts is not None]
    assert len(parts) == len(statuses)
    assert statuses[-1].model_fit is not None and statuses[-1].model_fit.misfit[0]
    assert max(p.degrading.max() for p in parts) > 0.9  # the filter alone would name parts
    assert not any(p.named.any() for p in parts) and all(np.all(np.isinf(p.eol)) for p in parts)

