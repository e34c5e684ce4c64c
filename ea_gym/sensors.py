"""Sensors: the measured signals of a system from its true energy variables, with white noise.

Every sensor reads one energy variable's conjugate signal through the monitor's measurement matrix
(an I element's flow, a C element's displacement) and adds white Gaussian noise whose std is a fixed
fraction of that signal's RMS over the window. ``add_sensor_noise`` draws from one generator;
``SystemNoise`` draws the same numbers for N systems at once, system i from its own generator.
"""

from __future__ import annotations

import operator
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from ea_gym._kernels.normal import bit_generator_addresses, noisy_rows
from ea_gym.threads import over_rows

if TYPE_CHECKING:
    from ea_gym.diagnosis.monitor import Monitor


def add_sensor_noise(signals: np.ndarray, fraction: float | np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Add white Gaussian noise of std ``fraction`` x the RMS of each signal over its time axis.

    ``fraction`` may be an array broadcasting against ``signals`` (one level per system).
    """
    if np.all(np.asarray(fraction) == 0):
        return signals
    rms = np.sqrt(np.mean(signals**2, axis=-1, keepdims=True))
    return signals + fraction * rms * rng.standard_normal(signals.shape)


def measure(monitor: Monitor, parameters: np.ndarray, states: np.ndarray, noise: float, rng: np.random.Generator) -> np.ndarray:
    """Sensor signals (N, nx, T) from true energy variables (N, T, nx) under true ``parameters`` (N, P) or (N, T, P)."""
    matrix = monitor.measurement_matrix(parameters)
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
