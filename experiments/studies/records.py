"""Records the code did not make: each system's equations written out by hand and integrated with scipy's ``solve_ivp``.

The acceptance studies (``real_machines.py``, ``compare_progpy.py``'s real-machine cases) test the chain on
signals that ea-gym's simulator did not produce: the equations below are read off the bond graphs of
``ea_gym/models.py`` and ``experiments/models/two_mass_chain.yaml`` and written in their energy variables (an
I element's momentum or flux linkage p, a C element's displacement or charge q), so that a part's value may
change while it stores energy (the flow is p / I at every instant, as ``ea_gym.sensors`` reads it). The
parameters follow piecewise-linear profiles (a constant healthy value, then a ramp from its onset), the load
is a multisine or a band-limited random sum of tones around the model's nominal load, and the sensors add
white noise of std ``noise`` x each signal's RMS over each 1 s step (``ea_gym.sensors.add_sensor_noise``'s
scaling), the load column too where asked. A record is an ``ea_gym.measurements.Measurements``: the chain
reads it exactly as a user's CSV.

:func:`plant_agreement` checks a record against ea-gym's own simulation (``ea_gym.plant.run_model``) of the
same machine and load: they agree to ~1e-7 of each signal's amplitude on the spring-mass-damper, where the
simulator's cubic load interpolation is exact to that order.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

from ea_gym.loads import Sine, SinesLoad
from ea_gym.measurements import Measurements
from ea_gym.model_files import load_system
from ea_gym.models import SystemModel
from ea_gym.plant import run_model
from ea_gym.sensors import Sensors

ROOT = Path(__file__).resolve().parents[2]
TWO_MASS = ROOT / "experiments" / "models" / "two_mass_chain.yaml"
SYSTEMS = ("spring_mass_damper", "rlc_circuit", "dc_motor", "two_mass_chain")
LOADS = ("multisine", "random")
RATE = 100.0  # Hz
NOISE = 0.01  # sensor noise, fraction of each signal's RMS over a step
STEP = 1.0  # s: the blocks the noise is scaled over (the chain's step)
RTOL, ATOL = 1e-9, 1e-12  # solve_ivp's tolerances (the energy variables are 1e-3 and more)

#: (energy variables, parameter values by name, load) -> the energy variables' rates
Rates = Callable[[Sequence[float], Mapping[str, float], float], tuple[float, ...]]


def spring_mass_damper(x: Sequence[float], p: Mapping[str, float], u: float) -> tuple[float, ...]:
    """[momentum of m, extension of k]: v = p_m / m; p_m' = F - k q - b v, q' = v."""
    momentum, q = x
    v = momentum / p["m"]
    return u - p["k"] * q - p["b"] * v, v


def rlc_circuit(x: Sequence[float], p: Mapping[str, float], u: float) -> tuple[float, ...]:
    """[flux linkage of L1, charge of C1]: i = lambda / L1, u_C = q / C1; lambda' = U - R1 i - u_C, q' = i - u_C / R2."""
    flux, q = x
    i, u_c = flux / p["L1"], q / p["C1"]
    return u - p["R1"] * i - u_c, i - u_c / p["R2"]


def dc_motor(x: Sequence[float], p: Mapping[str, float], u: float) -> tuple[float, ...]:
    """[flux linkage of La, angular momentum of J]: i = lambda / La, w = h / J; lambda' = V - Ra i - K w, h' = K i - bm w."""
    flux, h = x
    i, w = flux / p["La"], h / p["J"]
    return u - p["Ra"] * i - p["K"] * w, p["K"] * i - p["bm"] * w


def two_mass_chain(x: Sequence[float], p: Mapping[str, float], u: float) -> tuple[float, ...]:
    """[momentum of m1, extension of k1, of k2, momentum of m2]: v1 = p1 / m1, v2 = p2 / m2, the coupling force
    f = k2 q12 + b2 (v1 - v2); p1' = F - k1 q1 - b1 v1 - f, q1' = v1, q12' = v1 - v2, p2' = f."""
    p1, q1, q12, p2 = x
    v1, v2 = p1 / p["m1"], p2 / p["m2"]
    coupling = p["k2"] * q12 + p["b2"] * (v1 - v2)
    return u - p["k1"] * q1 - p["b1"] * v1 - coupling, v1, v1 - v2, coupling


EQUATIONS: dict[str, Rates] = {
    "spring_mass_damper": spring_mass_damper, "rlc_circuit": rlc_circuit, "dc_motor": dc_motor, "two_mass_chain": two_mass_chain,
}


def system_path(system: str) -> str:
    """What ``load_system`` (and ``ea-gym --system``) reads for ``system``: the built-in's name, or the two-mass model file."""
    return str(TWO_MASS) if system == "two_mass_chain" else system


@cache
def system_model(system: str) -> SystemModel:
    """The ea-gym model of ``system``: its names, nominal values and safe limits (its equations are not used here)."""
    return load_system(system_path(system))


@dataclass(frozen=True)
class Ramp:
    """A part wearing linearly from ``onset`` (s) at ``rate`` (its unit per s)."""

    parameter: str
    onset: float
    rate: float


@dataclass(frozen=True)
class Machine:
    """One machine of ``system``: every part's constant healthy value (SI; default the nominal) and the ramps that wear it."""

    system: str
    healthy: Mapping[str, float] = field(default_factory=dict)
    ramps: tuple[Ramp, ...] = ()

    def __post_init__(self) -> None:
        names = system_model(self.system).parameter_names
        for name in [*self.healthy, *(r.parameter for r in self.ramps)]:
            if name not in names:
                raise ValueError(f"machine: {name!r} is not a parameter of {self.system} ({', '.join(names)})")
        worn = [r.parameter for r in self.ramps]
        if len(set(worn)) != len(worn):
            raise ValueError(f"machine: one ramp per part, got {worn}")

    @property
    def base(self) -> np.ndarray:
        """Every parameter's healthy value, (P,) in ``parameter_names`` order."""
        return system_model(self.system).parameter_vector(self.healthy)

    def values(self, t: np.ndarray) -> np.ndarray:
        """Every parameter's value at times ``t`` (s), (..., P)."""
        t = np.asarray(t, dtype=float)
        names = system_model(self.system).parameter_names
        values = np.broadcast_to(self.base, t.shape + (len(names),)).copy()
        for ramp in self.ramps:
            values[..., names.index(ramp.parameter)] += ramp.rate * np.maximum(t - ramp.onset, 0.0)
        return values

    def end_of_life(self, ramp: Ramp) -> float:
        """When ``ramp``'s part reaches the safe limit it heads for (s)."""
        low, high = system_model(self.system).safe_limits[ramp.parameter]
        start = self.base[system_model(self.system).parameter_names.index(ramp.parameter)]
        return ramp.onset + ((high if ramp.rate > 0 else low) - start) / ramp.rate

    def degrading(self, t: np.ndarray) -> np.ndarray:
        """Whether each part with safe limits wears at times ``t``, (T, D) in the limits' (the chain's ``degradable``) order."""
        parts = list(system_model(self.system).safe_limits)
        truth = np.zeros((len(t), len(parts)), dtype=bool)
        for ramp in self.ramps:
            truth[:, parts.index(ramp.parameter)] = np.asarray(t) > ramp.onset
        return truth


#: the way each part with safe limits wears (+1 up, -1 down): springs soften, dampers, resistances and friction grow,
#: a capacitor loses capacitance, a magnet its torque constant, an insulation its parallel resistance, masses gather dirt
WEAR: dict[str, dict[str, int]] = {
    "spring_mass_damper": {"k": -1, "m": +1, "b": +1},
    "rlc_circuit": {"R1": +1, "L1": -1, "C1": -1, "R2": -1},
    "dc_motor": {"Ra": +1, "La": -1, "K": -1, "J": +1, "bm": +1},
    "two_mass_chain": {"m1": +1, "k1": -1, "b1": +1, "k2": -1, "m2": +1},
}
#: parts wearing together, by onset: (part, onset s, time from onset to its safe limit s); the first two or all three
MULTI_PART: dict[str, tuple[tuple[str, float, float], ...]] = {
    "spring_mass_damper": (("k", 40.0, 100.0), ("b", 55.0, 80.0), ("m", 70.0, 120.0)),
    "rlc_circuit": (("R1", 40.0, 100.0), ("C1", 55.0, 80.0), ("R2", 70.0, 120.0)),
    "dc_motor": (("Ra", 40.0, 100.0), ("bm", 55.0, 80.0), ("K", 70.0, 120.0)),
    "two_mass_chain": (("k2", 40.0, 100.0), ("b1", 55.0, 80.0), ("k1", 70.0, 120.0)),
}


#: the acceptance's cases: which parts wear, from what healthy values, over how long (s)
CASES = ("two parts", "three parts", "off-nominal", "single part")
DURATION = {"two parts": 200.0, "three parts": 200.0, "off-nominal": 200.0, "single part": 160.0}
SINGLE_PART = (40.0, 100.0)  # the single part's onset and time to its limit (s)
COMMISSIONING = 30.0  # s: a separate healthy record of an off-nominal machine, on another load


def worn(machine: Machine, wear: Sequence[tuple[str, float, float]], scale: float = 1.0) -> Machine:
    """``machine`` with each (part, onset, time to limit) of ``wear`` ramping from its healthy value to the safe limit
    in its ``WEAR`` direction, every time multiplied by ``scale``."""
    model = system_model(machine.system)
    ramps = []
    for parameter, onset, time_to_limit in wear:
        low, high = model.safe_limits[parameter]
        start = machine.base[model.parameter_names.index(parameter)]
        limit = high if WEAR[machine.system][parameter] > 0 else low
        ramps.append(Ramp(parameter, scale * onset, (limit - start) / (scale * time_to_limit)))
    return Machine(machine.system, machine.healthy, (*machine.ramps, *ramps))


def middle_half(system: str, rng: np.random.Generator) -> dict[str, float]:
    """Every part with safe limits at a value drawn uniformly in the middle half of its range."""
    limits = system_model(system).safe_limits
    return {name: float(low + (high - low) * rng.uniform(0.25, 0.75)) for name, (low, high) in limits.items()}


def draw_load(system: str, kind: str, rng: np.random.Generator) -> SinesLoad:
    """A load around ``system``'s nominal load of tones up to its excitation band: five of equal amplitude ("multisine")
    or forty of Rayleigh-distributed amplitudes ("random", band-limited noise); its fluctuations' RMS 30 % of the load's scale."""
    if kind not in LOADS:
        raise ValueError(f"load kind: expected one of {LOADS}, got {kind!r}")
    model = system_model(system)
    tones = 5 if kind == "multisine" else 40
    frequency = rng.uniform(0.05, model.excitation_bandwidth, tones)
    amplitude = np.ones(tones) if kind == "multisine" else rng.rayleigh(1.0, tones)
    amplitude *= 0.3 * model.random_load_scale * math.sqrt(2.0 / float(np.sum(amplitude**2)))
    phase = rng.uniform(0.0, 2.0 * np.pi, tones)
    return SinesLoad(model.nominal_load, tuple(Sine(float(a), float(f), float(ph)) for a, f, ph in zip(amplitude, frequency, phase)))


def equilibrium(system: str, values: np.ndarray, load: float) -> np.ndarray:
    """The energy variables at rest under a constant ``load`` with parameters ``values`` (P,): the rates' root (they are
    linear in the state: their columns read off unit states)."""
    rates, names = EQUATIONS[system], system_model(system).parameter_names
    p = dict(zip(names, map(float, values)))
    nx = len(system_model(system).state_names)
    offset = np.array(rates(np.zeros(nx), p, load))
    matrix = np.column_stack([np.array(rates(unit, p, load)) - offset for unit in np.eye(nx)])
    return np.asarray(np.linalg.solve(matrix, -offset))


def measured(system: str, states: np.ndarray, values: np.ndarray) -> np.ndarray:
    """What the sensors read, (T, nx): an I element's flow p / I (its value at that instant), a C element's q."""
    model = system_model(system)
    names = model.parameter_names
    signals = np.array(states, dtype=float)
    for j, name in enumerate(model.state_names):
        if model.graph.elements[name].kind.value == "I":
            signals[:, j] /= values[:, names.index(name)]
    return signals


def simulate(machine: Machine, load: SinesLoad, duration: float, rate: float = RATE) -> tuple[np.ndarray, np.ndarray]:
    """The machine's clean signals (T, nx) at ``rate`` Hz over ``duration`` s, from rest under its mean load, and the time grid (T,)."""
    system = machine.system
    rates, names = EQUATIONS[system], system_model(system).parameter_names
    t = np.arange(round(duration * rate) + 1) / rate
    base = machine.base
    ramps = [(names.index(r.parameter), r.onset, r.rate) for r in machine.ramps]
    amplitude = np.array([s.amplitude for s in load.sines])
    omega = 2.0 * np.pi * np.array([s.frequency for s in load.sines])
    phase = np.array([s.phase for s in load.sines])

    def derivative(time: float, x: np.ndarray) -> tuple[float, ...]:
        values = base.copy()
        for column, onset, slope in ramps:
            values[column] += slope * max(time - onset, 0.0)
        u = load.offset + float(amplitude @ np.sin(omega * time + phase))
        return rates(x, dict(zip(names, values)), u)

    start = equilibrium(system, machine.values(np.zeros(1))[0], load.offset)
    solution = solve_ivp(derivative, (0.0, float(t[-1])), start, t_eval=t, method="DOP853", rtol=RTOL, atol=ATOL)
    if not solution.success:
        raise RuntimeError(f"{system}: solve_ivp failed: {solution.message}")
    return t, measured(system, solution.y.T, machine.values(t))


def block_noise(signals: np.ndarray, fraction: float, samples: int, rng: np.random.Generator) -> np.ndarray:
    """``signals`` (T, k) with white noise of std ``fraction`` x each column's RMS over each block of ``samples``."""
    noisy = np.array(signals, dtype=float)
    for start in range(0, len(noisy), samples):
        block = noisy[start : start + samples]
        block += fraction * np.sqrt(np.mean(block**2, axis=0)) * rng.standard_normal(block.shape)
    return noisy


@dataclass(frozen=True)
class Record:
    """A machine's record and its truth.

    Attributes:
        machine: the true machine (healthy values, ramps).
        measurements: what its sensors and the load column say, as the chain reads a CSV.
        clean: the signals before noise, (T, nx); load: the true load (T,).
    """

    machine: Machine
    measurements: Measurements
    clean: np.ndarray
    load: np.ndarray


def make_record(
    machine: Machine, load: SinesLoad, duration: float, rng: np.random.Generator, noise: float = NOISE, load_noise: float = 0.0,
    rate: float = RATE,
) -> Record:
    """The machine under ``load`` for ``duration`` s, measured with ``noise`` on every signal and ``load_noise`` on the load."""
    t, clean = simulate(machine, load, duration, rate)
    samples = round(STEP * rate)
    signals = block_noise(clean, noise, samples, rng)
    true_load = load.value(t)
    column = block_noise(true_load[:, None], load_noise, samples, rng)[:, 0] if load_noise else true_load
    return Record(machine, Measurements(t=t, load=column, signals=signals), clean, true_load)


def plant_agreement(machine: Machine, load: SinesLoad, duration: float, rate: float = RATE) -> float:
    """The largest difference between this module's clean signals and ``ea_gym.plant.run_model``'s (measured through
    ``ea_gym.sensors.Sensors``) for the same machine and load, as a fraction of each signal's largest |value|."""
    t, ours = simulate(machine, load, duration, rate)
    model = system_model(machine.system)
    start = equilibrium(machine.system, machine.values(np.zeros(1))[0], load.offset)
    plant = run_model(model, t, load, machine.values, start)
    theirs = Sensors(model).measure(plant.parameters[None], plant.states[None], 0.0, np.random.default_rng(0))[0].T
    return float(np.max(np.abs(ours - theirs).max(axis=0) / np.abs(theirs).max(axis=0)))


def case_generator(system: str, case: str, seed: int) -> np.random.Generator:
    """The generator of a case's record: its load, its machine's healthy values, its noise."""
    return np.random.default_rng([2030, SYSTEMS.index(system), CASES.index(case), seed])


def case_machine(system: str, case: str, seed: int, rng: np.random.Generator, scale: float = 1.0) -> Machine:
    """The machine of one of ``CASES``: "two parts" and "three parts" wear the first two or three of ``MULTI_PART`` from
    nominal, "off-nominal" the first two from values drawn in the middle half of every part's range (``middle_half``),
    "single part" the seed's part of ``WEAR`` (cyclically) from nominal (``SINGLE_PART``); times multiplied by ``scale``."""
    if case not in CASES:
        raise ValueError(f"case: expected one of {CASES}, got {case!r}")
    healthy = middle_half(system, rng) if case == "off-nominal" else {}
    parts = list(WEAR[system])
    wear = {"three parts": MULTI_PART[system], "single part": [(parts[seed % len(parts)], *SINGLE_PART)]}.get(case, MULTI_PART[system][:2])
    return worn(Machine(system, healthy), wear, scale)


def case_record(system: str, case: str, seed: int, scale: float = 1.0, load_noise: float = 0.0) -> tuple[Record, Record]:
    """One of ``CASES``' records (the load random on even seeds, a multisine on odd ones; 1 % sensor noise, ``load_noise`` on
    the load column drawn after it, so that the sensors' noise does not depend on it), and a separate healthy record of
    the same machine on another load (``COMMISSIONING`` s x ``scale``) to commission the chain on."""
    rng = case_generator(system, case, seed)
    machine = case_machine(system, case, seed, rng, scale)
    load = draw_load(system, LOADS[seed % 2], rng)
    healthy = Machine(system, machine.healthy)
    commissioning = make_record(healthy, draw_load(system, LOADS[seed % 2], rng), scale * COMMISSIONING, rng)
    return make_record(machine, load, scale * DURATION[case], rng, load_noise=load_noise), commissioning
