"""Sensors: the measurement model of a system, and the sensors' white noise.

Every storage element has one sensor. It reads its energy variable's co-energy side: an I element's
flow f = p / I (a velocity, a current) and a C element's displacement q itself (a position, a
charge). ``Sensors(model)`` holds which signals are measured and the measurement matrix that maps the
energy variables to them under given parameter values; the plant, the monitor, the PHM chain, the
fault database and the environments all measure through it.

The noise is white and Gaussian, its std a fixed fraction of each signal's RMS over the window.
``add_sensor_noise`` draws from one generator; ``SystemNoise`` draws the same numbers for N systems
at once, system i from its own generator.

Example::

    sensors = Sensors(model)
    signals = sensors.measure(parameters, states, noise=0.01, rng=np.random.default_rng(0))
"""

from __future__ import annotations

import operator
from collections.abc import Sequence

import numpy as np

from ea_gym._kernels.normal import bit_generator_addresses, noisy_rows
from ea_gym.bondgraph.elements import Kind
from ea_gym.models import SystemModel
from ea_gym.threads import over_rows


def add_sensor_noise(signals: np.ndarray, fraction: float | np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Add white Gaussian noise of std ``fraction`` x the RMS of each signal over its time axis.

    ``fraction`` may be an array broadcasting against ``signals`` (one level per system).
    """
    if np.all(np.asarray(fraction) == 0):
        return signals
    rms = np.sqrt(np.mean(signals**2, axis=-1, keepdims=True))
    return signals + fraction * rms * rng.standard_normal(signals.shape)


class Sensors:
    """The measurement model of ``model``: one sensor per energy variable, in ``model.state_names`` order.

    The matrix is diagonal: 1 / I on each I element's momentum (its sensor reads the flow p / I,
    m/s or A), 1 on each C element's displacement (m or C).

    Attributes:
        signals: the measured signals, named after the storage element each sensor reads.
        momenta: (state index, parameter index) of every I element's momentum, read as p / I.
    """

    def __init__(self, model: SystemModel):
        space = model.state_space
        elements = model.graph.elements
        self.signals: tuple[str, ...] = tuple(space.state_names)
        self.momenta: tuple[tuple[int, int], ...] = tuple(
            (j, space.parameter_names.index(name)) for j, name in enumerate(space.state_names) if elements[name].kind is Kind.I
        )

    def gain(self, parameters: np.ndarray) -> np.ndarray:
        """The diagonal of ``matrix`` under ``parameters`` (..., P): (..., nx), 1 / I on each I element's momentum, 1 elsewhere."""
        return 1.0 / self.inverse_gain(parameters)

    def inverse_gain(self, parameters: np.ndarray) -> np.ndarray:
        """Per signal, the factor (..., nx) that turns it back into its energy variable: I on a momentum, 1 elsewhere."""
        factor = np.ones(np.shape(parameters)[:-1] + (len(self.signals),))
        for j, p in self.momenta:
            factor[..., j] = parameters[..., p]
        return factor

    def matrix(self, parameters: np.ndarray) -> np.ndarray:
        """Rows map energy variables to measured signals under true ``parameters`` (..., P): (..., nx, nx)."""
        return self.gain(parameters)[..., :, None] * np.eye(len(self.signals))

    def measure(self, parameters: np.ndarray, states: np.ndarray, noise: float, rng: np.random.Generator) -> np.ndarray:
        """Sensor signals (N, nx, T) from true energy variables (N, T, nx) under true ``parameters`` (N, P) or (N, T, P),
        with noise of std ``noise`` x each signal's RMS."""
        matrix = self.matrix(parameters)
        if matrix.ndim == 3:
            clean = np.einsum("nij,ntj->nit", matrix, states)
        else:
            clean = np.einsum("ntij,ntj->nit", matrix, states)
        return add_sensor_noise(clean, noise, rng)


class SystemNoise:
    """``add_sensor_noise`` on N systems' signals at once, system i drawing from its own generator.

    The same numbers as calling ``add_sensor_noise(clean[i], fraction, rngs[i])`` system by system, in
    one compiled loop over the systems, split over the kernel threads.

    Args:
        fraction: noise std as a fraction of each signal's RMS over the window.
    """

    def __init__(self, fraction: float):
        self.fraction = fraction
        # the generators whose addresses were last taken, holding them alive, and those addresses
        self._generators: tuple[tuple[np.random.Generator, ...], np.ndarray] = ((), np.empty((0, 4), dtype=np.uintp))
        self._distinct = True  # whether the generators' bit generators are distinct: their rows may run at once

    def __call__(self, clean: np.ndarray, rngs: Sequence[np.random.Generator]) -> np.ndarray:
        """Noisy copies of ``clean`` (N, nx, T); ``clean`` itself when the fraction is 0."""
        if self.fraction == 0:
            return clean
        clean = np.ascontiguousarray(clean, dtype=float)
        noisy = np.empty_like(clean)
        generators, fraction = self._addresses(rngs), float(self.fraction)

        def noisy_part(start: int, stop: int) -> None:
            rows = slice(start, stop)
            noisy_rows(generators[rows], clean[rows], fraction, noisy[rows])

        if self._distinct:
            over_rows(noisy_part, len(clean))
        else:  # a generator drawn for two systems: the systems' draws in order, on one thread
            noisy_part(0, len(clean))
        return noisy

    def _addresses(self, rngs: Sequence[np.random.Generator]) -> np.ndarray:
        """``bit_generator_addresses`` of every generator (N, 4), taken again only when the generators change."""
        known, addresses = self._generators
        if len(known) != len(rngs) or not all(map(operator.is_, known, rngs)):
            addresses = np.array([bit_generator_addresses(rng) for rng in rngs], dtype=np.uintp).reshape(-1, 4)
            self._generators = (tuple(rngs), addresses)
            self._distinct = len(np.unique(addresses[:, 0])) == len(addresses)  # no bit generator state shared
        return addresses
