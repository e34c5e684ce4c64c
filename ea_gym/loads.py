"""Loads: the time functions that drive a model's source.

A load's value is in the source's SI unit (N for a force source, V for a voltage source, ...)
and its derivative in that unit per second. Every load is an analytic function of continuous
time t (s), so an integrator may evaluate it at any instant and the result does not depend on
how the time axis is chunked.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

# the compiled form for many systems on uniform grids, as the environments draw their loads
from ea_gym._kernels.multisine import multisine_rotations, rotated_multisine, rotated_multisine_into

__all__ = ["ConstantLoad", "Load", "RandomLoad", "Sine", "SinesLoad", "multisine_rotations", "rotated_multisine", "rotated_multisine_into"]


@runtime_checkable
class Load(Protocol):
    """A time function driving a source; both methods work elementwise over any shape of t (s)."""

    def value(self, t: np.ndarray) -> np.ndarray:
        """The load at times t, in the source's unit (N, V, ...)."""
        ...

    def derivative(self, t: np.ndarray) -> np.ndarray:
        """d/dt of the load at times t, in the source's unit per second (N/s, V/s, ...)."""
        ...


def _multisine(
    t: np.ndarray, amplitudes: np.ndarray, frequencies: np.ndarray, phases: np.ndarray, derivative: bool
) -> np.ndarray:
    """sum_i a_i sin(2 pi f_i t + phi_i), or its time derivative, elementwise over t."""
    t = np.asarray(t, dtype=float)
    rows = max(1, _TERMS_AT_ONCE // max(len(frequencies), 1))
    if t.size > rows:  # times x sines angles in slices: a long run of many sines would otherwise hold them all at once
        flat = t.reshape(-1)
        parts = [_multisine(flat[k:k + rows], amplitudes, frequencies, phases, derivative) for k in range(0, flat.size, rows)]
        return np.concatenate(parts).reshape(t.shape)
    omega = 2.0 * np.pi * frequencies
    angle = t[..., None] * omega + phases
    if derivative:
        return np.cos(angle) @ (amplitudes * omega)
    return np.sin(angle) @ amplitudes


#: the most time x sine angles _multisine holds at once (8 MB of them)
_TERMS_AT_ONCE = 1 << 20


@dataclass(frozen=True)
class ConstantLoad:
    """A constant load of ``level`` (N, V, ...)."""

    level: float

    def value(self, t: np.ndarray) -> np.ndarray:
        return np.full(np.shape(t), float(self.level))

    def derivative(self, t: np.ndarray) -> np.ndarray:
        return np.zeros(np.shape(t))


@dataclass(frozen=True)
class Sine:
    """One sinusoid: ``amplitude`` (load unit), ``frequency`` (Hz, >= 0), ``phase`` (rad)."""

    amplitude: float
    frequency: float
    phase: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.frequency) and self.frequency >= 0):
            raise ValueError(f"sine frequency must be finite and >= 0 Hz, got {self.frequency!r}")


@dataclass(frozen=True)
class SinesLoad:
    """offset + sum of amplitude * sin(2 pi frequency t + phase) over ``sines`` (load unit)."""

    offset: float
    sines: tuple[Sine, ...]

    def _terms(self, t: np.ndarray, derivative: bool) -> np.ndarray:
        return _multisine(
            t,
            np.array([s.amplitude for s in self.sines], dtype=float),
            np.array([s.frequency for s in self.sines], dtype=float),
            np.array([s.phase for s in self.sines], dtype=float),
            derivative,
        )

    def value(self, t: np.ndarray) -> np.ndarray:
        return self.offset + self._terms(t, derivative=False)

    def derivative(self, t: np.ndarray) -> np.ndarray:
        return self._terms(t, derivative=True)


# eq=False: the fields hold arrays, for which the generated == would be ambiguous.
@dataclass(frozen=True, eq=False)
class RandomLoad:
    """A band-limited random load realised as a random-phase multisine.

    value(t) = mean + sum_i a sin(2 pi f_i t + phi_i) with n equal amplitudes a = std sqrt(2/n);
    with distinct frequencies its time-averaged mean is ``mean`` and its time-averaged standard
    deviation is ``std`` (both in the load unit). ``bandwidth`` (Hz) bounds the ``frequencies``
    (Hz); ``phases`` are in rad. Build one with :meth:`draw`.
    """

    mean: float
    std: float
    bandwidth: float
    frequencies: np.ndarray
    phases: np.ndarray

    def __post_init__(self) -> None:
        frequencies = np.array(self.frequencies, dtype=float)
        phases = np.array(self.phases, dtype=float)
        if frequencies.ndim != 1 or frequencies.shape != phases.shape or frequencies.size == 0:
            raise ValueError(
                f"frequencies and phases must be non-empty 1-D arrays of one length, "
                f"got shapes {frequencies.shape} and {phases.shape}"
            )
        if not self.std >= 0:
            raise ValueError(f"std must be >= 0, got {self.std!r}")
        if not (np.all(frequencies > 0) and np.all(frequencies <= self.bandwidth)):
            raise ValueError(f"frequencies must lie in (0, bandwidth = {self.bandwidth!r}] Hz")
        # Read-only copies keep the frozen load immutable.
        frequencies.flags.writeable = False
        phases.flags.writeable = False
        object.__setattr__(self, "frequencies", frequencies)
        object.__setattr__(self, "phases", phases)

    @classmethod
    def draw(
        cls, mean: float, std: float, bandwidth: float, rng: np.random.Generator, n_components: int = 64
    ) -> RandomLoad:
        """Frequencies uniform in (0, bandwidth] Hz and phases uniform in [0, 2 pi), from ``rng`` only."""
        if not (math.isfinite(bandwidth) and bandwidth > 0):
            raise ValueError(f"bandwidth must be finite and > 0 Hz, got {bandwidth!r}")
        if n_components < 1:
            raise ValueError(f"n_components must be >= 1, got {n_components!r}")
        # bandwidth - U[0, bandwidth) lies in (0, bandwidth]: no zero-frequency (constant) term.
        frequencies = bandwidth - rng.uniform(0.0, bandwidth, n_components)
        phases = rng.uniform(0.0, 2.0 * np.pi, n_components)
        return cls(mean=mean, std=std, bandwidth=bandwidth, frequencies=frequencies, phases=phases)

    @property
    def amplitude(self) -> float:
        """The common amplitude std sqrt(2/n) of the n components (load unit)."""
        return self.std * math.sqrt(2.0 / self.frequencies.size)

    def _terms(self, t: np.ndarray, derivative: bool) -> np.ndarray:
        amplitudes = np.full(self.frequencies.size, self.amplitude)
        return _multisine(t, amplitudes, self.frequencies, self.phases, derivative)

    def value(self, t: np.ndarray) -> np.ndarray:
        return self.mean + self._terms(t, derivative=False)

    def derivative(self, t: np.ndarray) -> np.ndarray:
        return self._terms(t, derivative=True)
