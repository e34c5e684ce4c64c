"""Records the chain did not make: each built-in system's equations written by hand and integrated by scipy's
solve_ivp (not ea-gym's discretization), its parameters constant, off nominal or ramping, under a multisine
load, the sensors (and the load, where asked) read with white noise of a fraction of each signal's RMS over
every 1 s step; and the chain driven over them, its reference model simulated at the parameters it is told
the healthy machine has."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from ea_gym.bondgraph.simulation import simulate_measured
from ea_gym.diagnosis.training import load_shipped_classifier
from ea_gym.models import SystemModel, get_model
from ea_gym.phm import HealthStatus, PHMChain, PHMConfig, chain_config, thresholds_for

RATE = 100.0  # Hz
STEP = 1.0  # s of signal per chain update, and the span of the noise's RMS

#: each system's energy variables' derivatives (momentum or flux, displacement or charge) under load u, and the
#: signals its sensors read (I: flow = momentum / inertia, C: displacement), in ``model.state_names`` order
Derivative = Callable[[np.ndarray, float, Mapping[str, float]], list[float]]
Signals = Callable[[np.ndarray, Mapping[str, np.ndarray]], np.ndarray]
EQUATIONS: dict[str, tuple[Derivative, Signals]] = {
    # [p, q]: p' = F - k q - b p / m, q' = p / m; signals [v, q]
    "spring_mass_damper": (
        lambda s, u, v: [u - v["k"] * s[1] - v["b"] * s[0] / v["m"], s[0] / v["m"]],
        lambda s, v: np.stack([s[0] / v["m"], s[1]]),
    ),
    # [flux of L1, charge of C1]: lambda' = U - R1 i - q / C1, q' = i - q / (R2 C1), i = lambda / L1; signals [i, q]
    "rlc_circuit": (
        lambda s, u, v: [u - v["R1"] * s[0] / v["L1"] - s[1] / v["C1"], s[0] / v["L1"] - s[1] / (v["R2"] * v["C1"])],
        lambda s, v: np.stack([s[0] / v["L1"], s[1]]),
    ),
    # [flux of La, momentum of J]: lambda' = V - Ra i - K w, h' = K i - bm w, i = lambda / La, w = h / J; signals [i, w]
    "dc_motor": (
        lambda s, u, v: [u - v["Ra"] * s[0] / v["La"] - v["K"] * s[1] / v["J"], v["K"] * s[0] / v["La"] - v["bm"] * s[1] / v["J"]],
        lambda s, v: np.stack([s[0] / v["La"], s[1] / v["J"]]),
    ),
}

#: each system's load: (mean, std of its variation) of the nominal load, and the multisine's top frequency (Hz)
LOADS = {"spring_mass_damper": (0.0, 1.0, 2.0), "rlc_circuit": (1.0, 0.5, 5.0), "dc_motor": (1.0, 0.5, 5.0)}


@dataclass(frozen=True)
class Fault:
    """Parameter ``name`` ramps at ``slope`` (its unit per s) from ``onset`` (s)."""

    name: str
    onset: float
    slope: float


@dataclass(frozen=True)
class Record:
    """One machine's record at ``RATE``.

    Attributes:
        model: the system.
        t: sample times (s), (T,).
        measured: the noisy sensor signals, (nx, T).
        load: the load as measured (with its noise, if any), (T,); load_rate: its central difference (1/s), (T,).
        true_load: the load the machine felt, (T,).
        truth: every parameter's true value at every sample, (P, T) in ``model.parameter_names`` order.
    """

    model: SystemModel
    t: np.ndarray
    measured: np.ndarray
    load: np.ndarray
    load_rate: np.ndarray
    true_load: np.ndarray
    truth: np.ndarray

    def parameter(self, name: str) -> np.ndarray:
        """Parameter ``name``'s true value at every sample, (T,)."""
        return self.truth[self.model.parameter_names.index(name)]


Function = Callable[[np.ndarray], np.ndarray]


def multisine(system: str, rng: np.random.Generator, lines: int = 12) -> tuple[Function, Function]:
    """The system's load (``LOADS``: ``lines`` tones of random frequencies and phases) and its derivative."""
    model = get_model(system)
    mean, spread, top = LOADS[system]
    frequency, phase = rng.uniform(0.05, top, lines), rng.uniform(0.0, 2 * np.pi, lines)
    amplitude = spread * model.nominal_load * np.sqrt(2.0 / lines)
    offset = mean * model.nominal_load

    def load(t: np.ndarray) -> np.ndarray:
        return offset + amplitude * np.sin(2 * np.pi * np.multiply.outer(t, frequency) + phase).sum(-1)

    def rate(t: np.ndarray) -> np.ndarray:
        return (amplitude * 2 * np.pi * frequency * np.cos(2 * np.pi * np.multiply.outer(t, frequency) + phase)).sum(-1)

    return load, rate


def band_limited(system: str, rng: np.random.Generator, duration: float) -> tuple[Function, Function]:
    """A band-limited random load: white noise low-passed below the system's top frequency (``LOADS``; a 4th-order
    Butterworth, forwards and backwards), scaled to the load's mean and spread, and its derivative, both through the
    cubic spline of its 1 kHz samples."""
    from scipy.interpolate import CubicSpline
    from scipy.signal import butter, sosfiltfilt

    model = get_model(system)
    mean, spread, top = LOADS[system]
    fine = 1000.0  # Hz
    t = np.arange(round((duration + 1.0) * fine) + 1) / fine
    filtered = sosfiltfilt(butter(4, top, fs=fine, output="sos"), rng.standard_normal(len(t)))
    spline = CubicSpline(t, model.nominal_load * (mean + spread * filtered / np.std(filtered)))
    derivative = spline.derivative()
    return (lambda x: spline(x)), (lambda x: derivative(x))


def noisy(signals: np.ndarray, fraction: float, rng: np.random.Generator) -> np.ndarray:
    """``signals`` (..., T) with white noise of std ``fraction`` x each 1 s step's RMS (the sensors' convention)."""
    out = signals.copy()
    step = round(STEP * RATE)
    for start in range(0, signals.shape[-1], step):
        chunk = signals[..., start : start + step]
        out[..., start : start + step] += fraction * np.sqrt(np.mean(chunk**2, axis=-1, keepdims=True)) * rng.standard_normal(chunk.shape)
    return out


def simulate(
    system: str, seed: int, duration: float, faults: Sequence[Fault] = (), offsets: Mapping[str, float] | None = None,
    noise: float = 0.01, load_noise: float = 0.0, random_load: bool = False,
) -> Record:
    """``system`` from rest for ``duration`` s under a multisine load (or a band-limited random one, ``random_load``;
    seed ``seed``): its parameters nominal, or at ``offsets`` (name -> value), plus the ``faults``' ramps; the
    sensors read with ``noise`` and the load with ``load_noise``."""
    rng = np.random.default_rng(seed)
    model = get_model(system)
    derivative, signals = EQUATIONS[system]
    load, _ = band_limited(system, rng, duration) if random_load else multisine(system, rng)
    base = {**dict(zip(model.parameter_names, model.parameter_vector())), **(offsets or {})}

    def parameters(t: np.ndarray | float) -> dict[str, np.ndarray]:
        values = {name: np.full(np.shape(t), value, dtype=float) for name, value in base.items()}
        for fault in faults:
            values[fault.name] = values[fault.name] + fault.slope * np.maximum(np.asarray(t) - fault.onset, 0.0)
        return values

    def rhs(t: float, state: np.ndarray) -> list[float]:
        return derivative(state, float(load(np.array([t]))[0]), {name: float(value) for name, value in parameters(t).items()})

    t = np.arange(round(duration * RATE) + 1) / RATE
    states = solve_ivp(rhs, (0.0, duration), [0.0, 0.0], t_eval=t, method="DOP853", rtol=1e-10, atol=1e-12).y
    truth = parameters(t)
    clean = signals(states, truth)
    true_load = load(t)
    measured_load = noisy(true_load, load_noise, rng) if load_noise > 0 else true_load
    return Record(
        model=model, t=t, measured=noisy(clean, noise, rng), load=measured_load, load_rate=np.gradient(measured_load, 1.0 / RATE),
        true_load=true_load, truth=np.stack([truth[name] for name in model.parameter_names]),
    )


def reference_signals(model: SystemModel, records: Sequence[Record], parameters: np.ndarray) -> np.ndarray:
    """The model's signals at ``parameters`` (N, P) under each record's measured load, from rest (where the records
    start), (N, nx, T): the reference the chain compares the machines with."""
    from ea_gym.sensors import Sensors

    load = np.stack([r.load for r in records])
    rate = np.stack([r.load_rate for r in records])
    signals, _ = simulate_measured(
        model.state_space, 1.0 / RATE, *model.source_inputs(load, rate), parameters, np.zeros((len(records), len(model.state_names))),
        Sensors(model).gain(parameters),
    )
    return signals


def run_chain(chain: PHMChain, records: Sequence[Record], reference: np.ndarray | None = None) -> list[HealthStatus]:
    """Every record (one per system of ``chain``) through ``chain`` step by step, the reference simulated at
    ``chain.reference_parameters`` unless given; the statuses of every step."""
    reference = reference_signals(chain.model, records, chain.reference_parameters) if reference is None else reference
    measured = np.stack([r.measured for r in records])
    load, rate = np.stack([r.load for r in records]), np.stack([r.load_rate for r in records])
    step = chain.step_samples
    statuses = []
    for start in range(0, measured.shape[-1] - step, step):
        part = slice(start, start + step + 1)
        statuses.append(chain.update(measured[..., part], reference[..., part], load[:, part], rate[:, part]))
    return statuses


def chain_for(system: str, n: int, config: PHMConfig | None = None) -> PHMChain:
    """A chain for ``n`` machines of ``system`` at the records' rate, 1 % noise (the CLI's settings by default)."""
    model = get_model(system)
    config = config or chain_config(RATE, 0.01)
    return PHMChain(model, load_shipped_classifier(model.name), thresholds_for(model, config, np.random.default_rng(0)), config, n)
