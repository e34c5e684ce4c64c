"""Commissioning (``ea_gym.phm.commission``, ``PHMChain.commission``): healthy machines whose parts sit anywhere in
the middle half of their safe range (each off nominal by up to a quarter of the span), their records made by
solve_ivp (``tests/ode_records.py``), 1 % sensor noise.

Measured on 60 s of signal (seeds 0-7 spring-mass-damper, 0-4 RLC circuit and DC motor): every value within 2.6
of its std (median |error| / std 0.55-1.3, the DC motor's J 2.3) and within 0.72 % of its span (median 0.03-0.57 %);
the chain with its nominal reference raised an alarm on every machine, commissioned on none, and named no part.
"""

from __future__ import annotations

import numpy as np
import pytest
from ode_records import Record, chain_for, run_chain, simulate

from ea_gym.models import get_model
from ea_gym.phm import Commissioning, commission

SECONDS = 60.0  # of healthy signal to commission from
RATE = 100.0


def healthy_machines(system: str, seeds: range) -> tuple[list[Record], np.ndarray]:
    """Records of machines whose every part is off nominal by a uniform draw within a quarter of its safe span, and those
    values (N, D) in the model's safe-limits order."""
    model = get_model(system)
    names = list(model.safe_limits)
    records, values = [], []
    for seed in seeds:
        draw = np.random.default_rng(1000 + seed).uniform(-0.25, 0.25, len(names))
        offsets = {name: model.nominal[name] + x * (high - low) for x, (name, (low, high)) in zip(draw, model.safe_limits.items())}
        records.append(simulate(system, seed, SECONDS + 60.0, offsets=offsets))
        values.append([offsets[name] for name in names])
    return records, np.array(values)


def commissioned(system: str, records: list[Record]) -> Commissioning:
    """``commission`` on each record's first ``SECONDS``."""
    n = round(SECONDS * RATE) + 1
    return commission(
        get_model(system), np.stack([r.measured[:, :n] for r in records]), np.stack([r.load[:n] for r in records]),
        np.stack([r.load_rate[:n] for r in records]), RATE, 0.01,
    )


@pytest.mark.parametrize("system", ["spring_mass_damper", "rlc_circuit", "dc_motor"])
def test_commissioning_recovers_each_part_and_the_commissioned_chain_sees_a_healthy_machine(system: str) -> None:
    model = get_model(system)
    records, truth_by_limits = healthy_machines(system, range(20, 25))
    fit = commissioned(system, records)
    truth = truth_by_limits[:, [list(model.safe_limits).index(name) for name in fit.names]]
    span = np.array([np.subtract(*model.safe_limits[name][::-1]) for name in fit.names])
    assert fit.value.shape == fit.std.shape == (len(records), len(fit.names))
    assert np.all(np.abs(fit.value - truth) <= 3 * fit.std)
    assert np.all(np.abs(fit.value - truth) <= 0.01 * span)
    # the nominal chain takes every machine for a faulty one; commissioned, it compares each with itself
    nominal, own = chain_for(system, len(records)), chain_for(system, len(records))
    own.commission(fit.value, std=fit.std)
    assert run_chain(nominal, records)[-1].alarm.all()
    statuses = run_chain(own, records)
    assert not any(s.alarm.any() for s in statuses)
    assert not any(s.parts is not None and (s.parts.named.any() or np.isfinite(s.parts.eol).any()) for s in statuses)
    assert statuses[-1].model_fit is not None and statuses[-1].model_fit.fits.all()


def test_commissioning_sets_the_reference_and_the_joint_filters_start() -> None:
    model = get_model("spring_mass_damper")
    chain = chain_for("spring_mass_damper", 3)
    values = np.array([[98.0, 10.3], [96.0, 9.8]])  # k, m of systems 0 and 2 (b's column below)
    values = np.column_stack([values, [0.52, 0.47]])
    chain.commission(values, systems=np.array([True, False, True]), std=np.full((2, 3), 1e-6))
    columns = [model.parameter_names.index(name) for name in chain.degradable]
    np.testing.assert_array_equal(chain.reference_parameters[[0, 2]][:, columns], values)
    np.testing.assert_array_equal(chain.reference_parameters[1], model.parameter_vector())
    joint = chain.joint
    assert joint is not None
    np.testing.assert_array_equal(joint.center[[0, 2]], values)
    # a prior tighter than the floor is floored at JointFilterConfig.commissioned_prior of the span
    span = np.array([np.subtract(*model.safe_limits[name][::-1]) for name in chain.degradable])
    np.testing.assert_allclose(joint.prior_std[[0, 2]], np.broadcast_to(chain.config.joint.commissioned_prior * span, (2, 3)))
    chain.reset()  # a reset keeps the machine's own values
    np.testing.assert_array_equal(joint.center[[0, 2]], values)
    with pytest.raises(ValueError, match="values must be"):
        chain.commission(values[:1], systems=np.array([True, False, True]))
    with pytest.raises(ValueError, match="measured must be"):
        commission(model, np.zeros((1, 3, 200)), np.zeros((1, 200)), np.zeros((1, 200)), RATE, 0.01)
