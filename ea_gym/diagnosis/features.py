"""Isolation features over a frame of EA residuals (paper 3.2, 4.2).

A frame is the last F sub-windows of the monitor's output; the STFT window is the whole frame, as the
paper asks (it equals the duration of the database runs' frames the classifier is trained on).

Two feature sets:

* ``paper``: the peaks of the spectrum of the I element's EA residual (frequency and amplitude of the
  three largest, noisy peaks removed): the paper's variant.
* ``strong``: for every element the relative EA residual over the frame and over each half of it,
  every component's EAI residual, the least-squares relative deviations beta of the junction power
  balance, the measured signals' noise level, and the paper's peaks.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np

from ea_gym.numerics import TINY

N_PEAKS = 3
VARIANTS = ("paper", "strong")


@dataclass(frozen=True)
class Frame:
    """Monitor output accumulated over one frame, for N systems.

    Attributes:
        ea, ea_reference: EA per element and sub-window (J), (N, E, F).
        gram, cross: power-balance least-squares statistics summed over the frame, (N, C, C) and (N, C).
        noise: relative noise level of each measured signal, (N, nx).
        sub_window: sub-window length (s).
        component_index: positions of the R, C, I components among the E elements.
        inertia_index: position of the I element whose residual the paper's variant uses.
    """

    ea: np.ndarray
    ea_reference: np.ndarray
    gram: np.ndarray
    cross: np.ndarray
    noise: np.ndarray
    sub_window: float
    component_index: np.ndarray
    inertia_index: int

    @property
    def residual(self) -> np.ndarray:
        """EA residual r = EA_real - EA_ref per element and sub-window (J), (N, E, F)."""
        return self.ea - self.ea_reference


@cache
def hann_window(length: int) -> np.ndarray:
    """scipy's periodic Hann window of ``length`` samples (the STFT's default), computed once per length, read-only."""
    from scipy.signal import get_window

    window = get_window("hann", length)
    window.flags.writeable = False
    return window


def residual_spectrogram(residual: np.ndarray, sub_window: float, frame: int, hop: int) -> tuple[np.ndarray, ...]:
    """Time-frequency map of an EA residual series (Fig 9): frequencies (Hz), segment times (s), |STFT|."""
    from scipy.signal import stft  # scipy.signal takes most of a second to import: only once a frame is classified

    frequencies, times, Z = stft(
        residual, fs=1.0 / sub_window, window=hann_window(frame), nperseg=frame, noverlap=frame - hop, boundary=None, padded=False,
        detrend="constant",
    )
    return frequencies, times, np.abs(Z)


def spectral_peaks(
    residual: np.ndarray, sub_window: float, scale: np.ndarray, max_frequency: float, min_relative: float = 0.05
) -> np.ndarray:
    """Frequencies (Hz) and relative amplitudes of the N_PEAKS largest peaks of each residual's spectrum.

    Peaks above ``max_frequency`` or below ``min_relative`` of the largest peak are noise and dropped
    (the paper's "noisy peaks"); missing peaks are zeros. Amplitudes are divided by ``scale`` (the
    frame's mean reference EA) so that they do not depend on the load's size.

    Args:
        residual: (N, F) series, one frame each.
        scale: (N,) in J.

    Returns:
        (N, 2 N_PEAKS): [f_1, a_1, f_2, a_2, ...], largest first.
    """
    frequencies, _, magnitude = residual_spectrogram(residual, sub_window, residual.shape[-1], residual.shape[-1])
    magnitude = magnitude[..., 0] / np.maximum(scale, TINY)[:, None]
    out = np.zeros((len(residual), 2 * N_PEAKS))
    # every row at once: a peak is a sample above both neighbours (scipy's find_peaks without options)
    inner = magnitude[:, 1:-1]
    peak = np.zeros(magnitude.shape, dtype=bool)
    peak[:, 1:-1] = (inner > magnitude[:, :-2]) & (inner > magnitude[:, 2:])
    peak &= frequencies <= max_frequency
    candidate = np.where(peak, magnitude, -np.inf)
    top = candidate.max(axis=1, initial=-np.inf)
    peak &= magnitude >= min_relative * top[:, None]
    candidate = np.where(peak, magnitude, -np.inf)
    order = np.argsort(-candidate, axis=1, kind="stable")[:, :N_PEAKS]
    found = np.take_along_axis(peak, order, axis=1)
    out[:, 0::2] = np.where(found, frequencies[order], 0.0)
    out[:, 1::2] = np.where(found, np.take_along_axis(magnitude, order, axis=1), 0.0)
    # a flat top (equal neighbours) or equal peaks: scipy's plateau rule and its sort's order decide, row by row
    ranked = np.sort(candidate, axis=1)
    tied = np.any(magnitude[:, 1:] == magnitude[:, :-1], axis=1) | np.any((ranked[:, 1:] == ranked[:, :-1]) & np.isfinite(ranked[:, 1:]), axis=1)
    for row in np.flatnonzero(tied):
        out[row] = _peaks_of(magnitude[row], frequencies, max_frequency, min_relative)
    return out


def _peaks_of(spectrum: np.ndarray, frequencies: np.ndarray, max_frequency: float, min_relative: float) -> np.ndarray:
    """``spectral_peaks`` of one spectrum through scipy's ``find_peaks`` (plateaus, ties)."""
    from scipy.signal import find_peaks

    out = np.zeros(2 * N_PEAKS)
    peaks, _ = find_peaks(spectrum)
    peaks = peaks[frequencies[peaks] <= max_frequency]
    if len(peaks) == 0:
        return out
    peaks = peaks[spectrum[peaks] >= min_relative * spectrum[peaks].max()]
    best = peaks[np.argsort(spectrum[peaks])[::-1][:N_PEAKS]]
    out[0 : 2 * len(best) : 2] = frequencies[best]
    out[1 : 2 * len(best) : 2] = spectrum[best]
    return out


def _relative(numerator: np.ndarray, denominator: np.ndarray) -> np.ndarray:
    return numerator / np.maximum(denominator, TINY)


def balance_deviation(gram: np.ndarray, cross: np.ndarray, limit: float = 1.0) -> np.ndarray:
    """Least-squares beta of the power-balance residual on the component powers, clipped to [-limit, limit].

    beta_i estimates the relative deviation of component i's constitutive coefficient; a small ridge
    keeps it finite when a component is barely excited.
    """
    ridge = 1e-9 * np.trace(gram, axis1=-2, axis2=-1)[..., None, None] * np.eye(gram.shape[-1])
    beta = np.linalg.solve(gram + ridge + TINY * np.eye(gram.shape[-1]), cross[..., None])[..., 0]
    return np.clip(beta, -limit, limit)


def frame_features(frame: Frame, variant: str, max_frequency: float = 2.0) -> np.ndarray:
    """Feature vectors (N, n_features) of one variant for a batch of frames."""
    if variant not in VARIANTS:
        raise ValueError(f"variant must be one of {VARIANTS}, got {variant!r}")
    residual = frame.residual
    reference_mean = frame.ea_reference.mean(axis=-1)
    i = frame.inertia_index
    peaks = spectral_peaks(residual[:, i], frame.sub_window, reference_mean[:, i], max_frequency)
    if variant == "paper":
        return peaks
    half = frame.ea.shape[-1] // 2
    relative = [
        _relative(residual[..., part].sum(-1), frame.ea_reference[..., part].sum(-1))
        for part in (slice(None), slice(None, half), slice(half, None))
    ]
    components = frame.component_index
    ea_c, ref_c = frame.ea[:, components].sum(-1), frame.ea_reference[:, components].sum(-1)
    eai_residual = _relative(ea_c, ea_c.sum(-1, keepdims=True)) - _relative(ref_c, ref_c.sum(-1, keepdims=True))
    beta = balance_deviation(frame.gram, frame.cross)
    return np.concatenate([*relative, eai_residual, beta, frame.noise, peaks], axis=-1)
