"""Multisine loads on uniform time grids, many systems at once: sum_i sin(2 pi f_i t + phi_i) and its
time derivative by rotating each term from one sample to the next (``ea_gym.loads`` holds the loads).

Reference (the specification in plain numpy): ``ea_gym._kernels.reference.multisine``.
"""

from __future__ import annotations

import math

import numba
import numpy as np

#: Samples between direct evaluations in ``rotated_multisine``: the rotation's round-off grows by about
#: 1e-16 per sample, so it stays below 1e-13 of each component's amplitude.
ROTATION_SPAN = 128


#: Systems ``rotated_multisine`` takes side by side: their terms' rotation states stay in the first-level cache.
SYSTEMS_BLOCK = 64


@numba.njit(cache=True)
def multisine_rotations(frequencies: np.ndarray, step: float) -> np.ndarray:
    """What ``rotated_multisine`` rotates each term by from one sample to the next, (N, 3, C): the
    angular frequencies 2 pi f (rad/s) of the frequencies f (N, C) in Hz, and the sine and cosine of
    the angle 2 pi f ``step`` (``step`` in s)."""
    n_sys, components = frequencies.shape
    rotation = np.empty((n_sys, 3, components))
    for n in range(n_sys):
        for i in range(components):
            omega = 2.0 * math.pi * frequencies[n, i]
            rotation[n, 0, i] = omega
            rotation[n, 1, i], rotation[n, 2, i] = math.sin(omega * step), math.cos(omega * step)
    return rotation


@numba.njit(cache=True)
def rotated_multisine(t: np.ndarray, phases: np.ndarray, rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """sum_i sin(2 pi f_i t + phi_i) and its time derivative (1/s) for N systems on uniform time grids.

    Every ``ROTATION_SPAN`` samples each term is evaluated directly; in between it is rotated by the
    angle 2 pi f_i step, four multiplications in place of a sine and a cosine.

    Args:
        t: times (N, T) in s, row n spaced by the step the rotations were made for.
        phases: phi (N, C) in rad.
        rotation: the terms' ``multisine_rotations`` (N, 3, C), which a caller may keep while the
            frequencies and the sample period stay.

    Returns:
        the sums and their derivatives, both (N, T).
    """
    total = np.empty(t.shape)
    slope = np.empty(t.shape)
    # offset 0 and scale 1 leave the sums' bits as they are (a sum from +0.0 is never -0.0)
    rotated_multisine_into(t, phases, rotation, np.zeros(len(t)), np.ones(len(t)), total, slope)
    return total, slope


@numba.njit(cache=True, nogil=True)
def rotated_multisine_into(
    t: np.ndarray, phases: np.ndarray, rotation: np.ndarray, offset: np.ndarray, scale: np.ndarray, total: np.ndarray, slope: np.ndarray
) -> None:
    """offset + scale x ``rotated_multisine`` into ``total`` and scale x its derivative into ``slope`` (N, T),
    with each system's ``offset`` and ``scale`` (N,) (a load's mean and amplitude). Each system's arithmetic
    is its own (the same in any block, in any lane), so a batch's rows may be split over threads
    (``ea_gym.threads.over_rows``)."""
    n_sys, n_samples = t.shape
    components = phases.shape[1]
    B = min(SYSTEMS_BLOCK, n_sys)
    # component-major copies, system innermost (the SIMD axis); each sample's sums over the
    # components are made in registers, in the components' order
    omega, sin_step, cos_step, s, c = np.empty((5, components, B))
    wave, rate = np.empty(B), np.empty(B)
    for n0 in range(0, n_sys, B):
        lanes = min(B, n_sys - n0)
        for i in range(components):
            for b in range(lanes):
                omega[i, b], sin_step[i, b], cos_step[i, b] = rotation[n0 + b, 0, i], rotation[n0 + b, 1, i], rotation[n0 + b, 2, i]
        for k in range(n_samples):
            if k % ROTATION_SPAN == 0:
                for i in range(components):
                    for b in range(lanes):
                        angle = t[n0 + b, k] * omega[i, b] + phases[n0 + b, i]
                        s[i, b], c[i, b] = math.sin(angle), math.cos(angle)
            wave[:] = 0.0
            rate[:] = 0.0
            for i in range(components):
                for b in range(lanes):
                    wave[b] += s[i, b]
                    rate[b] += omega[i, b] * c[i, b]
                    s[i, b], c[i, b] = s[i, b] * cos_step[i, b] + c[i, b] * sin_step[i, b], c[i, b] * cos_step[i, b] - s[i, b] * sin_step[i, b]
            for b in range(lanes):
                total[n0 + b, k] = offset[n0 + b] + scale[n0 + b] * wave[b]
                slope[n0 + b, k] = scale[n0 + b] * rate[b]
