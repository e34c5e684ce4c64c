"""Multisine loads (``ea_gym._kernels.multisine``): the sums of sines and their derivatives. The kernel
rotates each term from sample to sample and evaluates it afresh every ``ROTATION_SPAN`` samples, so it
meets these direct sums to ~1e-12 per term."""

from __future__ import annotations

import numpy as np


def multisine_rotations(frequencies: np.ndarray, step: float) -> np.ndarray:
    """(N, 3, C): the angular frequencies 2 pi f, and the sine and cosine of 2 pi f ``step``."""
    omega = 2.0 * np.pi * frequencies
    return np.stack([omega, np.sin(omega * step), np.cos(omega * step)], axis=1)


def rotated_multisine(t: np.ndarray, phases: np.ndarray, rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """sum_i sin(omega_i t + phi_i) and its time derivative, (N, T) each."""
    omega = rotation[:, 0]
    angle = t[:, :, None] * omega[:, None, :] + phases[:, None, :]
    return np.sin(angle).sum(-1), (np.cos(angle) * omega[:, None, :]).sum(-1)


def rotated_multisine_into(
    t: np.ndarray, phases: np.ndarray, rotation: np.ndarray, offset: np.ndarray, scale: np.ndarray, total: np.ndarray, slope: np.ndarray
) -> None:
    """offset + scale x ``rotated_multisine`` into ``total``, scale x its derivative into ``slope``."""
    wave, rate = rotated_multisine(t, phases, rotation)
    total[:] = offset[:, None] + scale[:, None] * wave
    slope[:] = scale[:, None] * rate
