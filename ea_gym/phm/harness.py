"""Running signals through a chain: a scenario's simulation, or signals recorded elsewhere."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from ea_gym.bondgraph.simulation import simulate_measured
from ea_gym.diagnosis.classifier import FaultClassifier
from ea_gym.models import SystemModel
from ea_gym.phm.chain import HealthStatus, PHMChain
from ea_gym.phm.config import PHMConfig
from ea_gym.phm.detection import calibrate_thresholds
from ea_gym.scenario import Scenario
from ea_gym.sensors import add_sensor_noise, measure

#: wraps the iterable of step starts, e.g. in a progress bar
Progress = Callable[[Iterable[int]], Iterable[int]]


@dataclass(frozen=True)
class ChainRun:
    """A scenario run through the chain: the statuses of every step and the ground truth.

    Attributes:
        statuses: the chain's record of every step.
        t: end of every step (s), (steps,).
        true_parameters: the plant's parameters at the end of every step, (steps, P).
        residual_series: EA residual of every element per sub-window (J), (E, sub-windows of the run).
    """

    statuses: list[HealthStatus]
    t: np.ndarray
    true_parameters: np.ndarray
    residual_series: np.ndarray


def nominal_reference(chain: PHMChain, measured: np.ndarray, load: np.ndarray, load_rate: np.ndarray) -> np.ndarray:
    """The nominal model's signals under the load, started from the first measured sample, (N, nx, T)."""
    nominal = np.repeat(chain.model.parameter_vector()[None], len(measured), 0)
    gain = chain.monitor.measurement_gain(nominal)
    signals, _ = simulate_measured(
        chain.model.state_space, chain.h, load[..., None], load_rate[..., None], nominal, measured[..., 0] / gain, gain
    )
    return signals


def run_signals(
    chain: PHMChain,
    measured: np.ndarray,
    load: np.ndarray,
    load_rate: np.ndarray,
    reference: np.ndarray | None = None,
    noise: Callable[[np.ndarray], np.ndarray] | None = None,
    progress: Progress | None = None,
) -> list[HealthStatus]:
    """Feed signals sampled at the chain's sample rate through ``chain`` (reset first), one step at a time.

    Args:
        measured: measured signals (flows of I, displacements of C), (N, nx, T): recorded, or a
            simulation's clean signals with ``noise``.
        load, load_rate: the source's value and time derivative, (N, T).
        reference: the reference model's signals, as ``measured``; None: ``nominal_reference``.
        noise: adds sensor noise to each step's chunk (its first sample shared with the previous one),
            None for recorded signals.
        progress: wraps the step starts.

    Returns:
        the chain's status after every whole step.
    """
    n, nx = chain.n, len(chain.model.state_names)
    if measured.ndim != 3 or measured.shape[:2] != (n, nx):
        raise ValueError(f"measured must be (N, nx, T) = ({n}, {nx}, T) signals, got shape {measured.shape}")
    if load.shape != (n, measured.shape[2]) or load_rate.shape != load.shape:
        raise ValueError(f"load and load_rate must be (N, T) = {(n, measured.shape[2])}, got {load.shape} and {load_rate.shape}")
    reference = nominal_reference(chain, measured, load, load_rate) if reference is None else reference
    step = chain.step_samples
    statuses = []
    chain.reset()
    starts: Iterable[int] = range(0, measured.shape[2] - step, step)
    for start in starts if progress is None else progress(starts):
        part = slice(start, start + step + 1)
        chunk = measured[..., part] if noise is None else noise(measured[..., part])
        statuses.append(chain.update(chunk, reference[..., part], load[:, part], load_rate[:, part]))
    return statuses


def run_scenario(scenario: Scenario, chain: PHMChain, rng: np.random.Generator, progress: Progress | None = None) -> ChainRun:
    """Simulate ``scenario``'s plant and the reference model and feed them step by step through ``chain`` (N = 1)."""
    from ea_gym.plant import run_model

    model = scenario.model
    t = scenario.times()
    load = scenario.make_load()
    plant = run_model(model, t, load, scenario.parameters_at, scenario.initial_state_vector())
    reference = run_model(model, t, load, None, scenario.initial_state_vector())
    nominal = model.parameter_vector()[None]
    clean = measure(chain.monitor, plant.parameters[None], plant.states[None], 0.0, rng)
    expected = measure(chain.monitor, nominal, reference.states[None], 0.0, rng)
    statuses = run_signals(
        chain, clean, load.value(t)[None], load.derivative(t)[None], expected,
        noise=lambda chunk: add_sensor_noise(chunk, chain.config.noise, rng), progress=progress,
    )
    ends = np.array([s.t[0] for s in statuses])
    index = np.round(ends * scenario.sample_rate).astype(int)
    residuals = np.concatenate([s.sub_residual[0] for s in statuses], -1)
    return ChainRun(statuses=statuses, t=ends, true_parameters=plant.parameters[index], residual_series=residuals)


def build_chain(
    model: SystemModel, config: PHMConfig, classifier: FaultClassifier, rng: np.random.Generator, n_systems: int = 1
) -> PHMChain:
    """A chain for ``model`` with its detection thresholds calibrated at ``config.noise``."""
    return PHMChain(model, classifier, calibrate_thresholds(model, config, rng), config, n_systems)


def classifier_for(model: SystemModel, rng: np.random.Generator, path: str | None = None) -> FaultClassifier:
    """The isolation network: from ``path``, else the one shipped for the model, else trained now."""
    from ea_gym.diagnosis.training import (
        load_shipped_classifier,
        shipped_classifier_path,
        train_isolation,
    )

    if path is not None:
        return FaultClassifier.load(path)
    if shipped_classifier_path(model.name).is_file():
        return load_shipped_classifier(model.name)
    return train_isolation(model, rng, variants=("strong",)).classifiers["strong"]
