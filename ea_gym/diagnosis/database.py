"""The fault database (paper 3.2, 4.2): simulated faults, their frame features and labels.

Each degradable parameter's range between its safe limits is cut into 20 intervals (Table 2); every
grid value is a run with that parameter held there (the nominal value is a fault-free run), under
several random loads and noise levels, beside extra fault-free runs. The plant and the reference
model start at rest together; frames end at several times of each run. Runs, not frames, are split
70/15/15 into training, validation and test sets, so no run's frames leak across sets.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ea_gym.bondgraph.simulation import simulate_batch
from ea_gym.diagnosis.features import VARIANTS, frame_features
from ea_gym.diagnosis.monitor import Monitor, MonitorConfig, MonitorWindow
from ea_gym.loads import RandomLoad
from ea_gym.models import SystemModel
from ea_gym.sensors import Sensors, add_sensor_noise


@dataclass(frozen=True)
class DatabaseConfig:
    """How the database is simulated.

    Attributes:
        intervals: intervals between the safe limits of each parameter (the paper: 20).
        noise_levels: sensor noise fractions of RMS simulated for every fault.
        n_loads: random loads (mean nominal, std 20-40 % of it, the model's excitation bandwidth).
        fault_free_runs: extra fault-free runs per load and noise level.
        frame: isolation frame (s); the STFT window.
        frame_ends: end times of the frames taken from each run (s); the run lasts until the last one.
        chunk: seconds of signal the monitor takes at a time (as an environment step would).
        sample_rate: Hz.
        split: training, validation and test fractions of the runs.
    """

    intervals: int = 20
    noise_levels: tuple[float, ...] = (0.0, 0.01, 0.05)
    n_loads: int = 8
    fault_free_runs: int = 17
    frame: float = 20.0
    frame_ends: tuple[float, ...] = (40.0, 50.0, 60.0)
    chunk: float = 1.0
    sample_rate: float = 100.0
    split: tuple[float, float, float] = (0.70, 0.15, 0.15)


@dataclass(frozen=True)
class FaultDatabase:
    """Features and labels of every frame.

    Attributes:
        classes: class names, "none" first, then the degradable parameters.
        features: variant name -> (n_frames, n_features).
        labels: class index per frame.
        magnitude: fraction of the way from nominal to the safe limit on the fault's side, in [0, 1].
        noise: sensor noise fraction per frame.
        run: run index per frame; split: 0 training, 1 validation, 2 test.
    """

    classes: tuple[str, ...]
    features: dict[str, np.ndarray]
    labels: np.ndarray
    magnitude: np.ndarray
    noise: np.ndarray
    run: np.ndarray
    split: np.ndarray

    def subset(self, split: int, variant: str) -> tuple[np.ndarray, np.ndarray]:
        mask = self.split == split
        return self.features[variant][mask], self.labels[mask]


def draw_loads(model: SystemModel, n: int, rng: np.random.Generator) -> list[RandomLoad]:
    """Random loads around the model's nominal load that excite its dynamics."""
    return [
        RandomLoad.draw(
            mean=model.nominal_load,
            std=model.random_load_scale * rng.uniform(0.2, 0.4),
            bandwidth=model.excitation_bandwidth,
            rng=rng,
        )
        for _ in range(n)
    ]


def classes_of(model: SystemModel) -> tuple[str, ...]:
    """Isolation classes: fault-free, then each degradable parameter (those with safe limits)."""
    return ("none", *model.safe_limits)


def build_database(
    model: SystemModel,
    rng: np.random.Generator,
    config: DatabaseConfig = DatabaseConfig(),
    monitor_config: MonitorConfig = MonitorConfig(),
) -> FaultDatabase:
    """Simulate every run of the database and compute both feature variants of every frame."""
    classes = classes_of(model)
    nominal = model.parameter_vector()
    loads = draw_loads(model, config.n_loads, rng)
    runs: list[tuple[int, str | None, float, int, float]] = []  # (class, parameter, value, load, noise)
    for label, name in enumerate(classes[1:], start=1):
        lower, upper = model.safe_limits[name]
        for value in np.linspace(lower, upper, config.intervals + 1):
            is_nominal = bool(np.isclose(value, model.nominal[name], rtol=1e-9))
            for load in range(config.n_loads):
                for noise in config.noise_levels:
                    runs.append((0 if is_nominal else label, name, float(value), load, noise))
    for load in range(config.n_loads):
        for noise in config.noise_levels:
            runs += [(0, None, float("nan"), load, noise)] * config.fault_free_runs

    n = len(runs)
    theta = np.repeat(nominal[None], n, axis=0)
    magnitude = np.zeros(n)
    for i, (label, parameter, value, _, _) in enumerate(runs):
        if label == 0 or parameter is None:  # fault-free (a nominal value or no fault)
            continue
        j = model.parameter_names.index(parameter)
        theta[i, j] = value
        lower, upper = model.safe_limits[parameter]
        magnitude[i] = (value - nominal[j]) / ((lower if value < nominal[j] else upper) - nominal[j])

    h = 1.0 / config.sample_rate
    t = np.arange(int(round(config.frame_ends[-1] * config.sample_rate)) + 1) * h
    load_index = np.array([r[3] for r in runs])
    u_loads, du_loads = model.source_inputs(np.stack([load.value(t) for load in loads]), np.stack([load.derivative(t) for load in loads]))
    u, du = u_loads[load_index], du_loads[load_index]
    space = model.state_space
    x0 = np.zeros((n, len(space.state_names)))
    plant = simulate_batch(space, h, u, du, theta, x0)
    reference = simulate_batch(space, h, u_loads, du_loads, np.repeat(nominal[None], config.n_loads, 0), x0[: config.n_loads])

    monitor = Monitor(model, h, monitor_config, n_systems=n)
    sensors = Sensors(model)
    measured = np.einsum("nij,ntj->nit", sensors.matrix(theta), plant)
    expected = np.einsum("ij,ntj->nit", sensors.matrix(nominal), reference)[load_index]
    noise_std = np.array([r[4] for r in runs])  # relative to each signal's RMS
    chunk = int(round(config.chunk * config.sample_rate))
    windows: list[MonitorWindow] = []
    for start in range(0, len(t) - 1, chunk):
        part = slice(start, start + chunk + 1)
        noisy = add_sensor_noise(measured[..., part], noise_std[:, None, None], rng)
        windows.append(monitor.update(noisy, expected[..., part], u[:, part, 0]))

    per_frame = int(round(config.frame / config.chunk))
    frames = []
    for end in config.frame_ends:
        last = int(round(end / config.chunk))
        frames.append(monitor.frame(windows[last - per_frame : last]))
    features = {v: np.concatenate([frame_features(f, v, model.excitation_bandwidth) for f in frames]) for v in VARIANTS}

    order = rng.permutation(n)
    cut = np.cumsum([int(round(f * n)) for f in config.split[:2]])
    split = np.empty(n, dtype=int)
    split[order[: cut[0]]], split[order[cut[0] : cut[1]]], split[order[cut[1] :]] = 0, 1, 2
    repeat = len(config.frame_ends)
    return FaultDatabase(
        classes=classes,
        features=features,
        labels=np.tile([r[0] for r in runs], repeat),
        magnitude=np.tile(magnitude, repeat),
        noise=np.tile(noise_std, repeat),
        run=np.tile(np.arange(n), repeat),
        split=np.tile(split, repeat),
    )
