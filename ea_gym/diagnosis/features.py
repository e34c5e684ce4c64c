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

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache, partial

import numpy as np

from ea_gym._kernels.features import frame_sums, peak_and_deviation_features, spectrum_peaks
from ea_gym.numerics import TINY
from ea_gym.threads import over_rows

N_PEAKS = 3
#: the smallest peak kept, relative to the largest: the smaller ones are noise
MIN_RELATIVE = 0.05
#: the ridge on the balance regression's normal equations, relative to their trace: keeps beta finite
#: where a component is barely excited
BALANCE_RIDGE = 1e-9
#: beta is clipped to [-BALANCE_LIMIT, BALANCE_LIMIT]
BALANCE_LIMIT = 1.0
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
    """Time-frequency map of an EA residual series (Fig 9): frequencies (Hz), segment times (s), |STFT|.

    scipy's ``stft`` (Hann window, each segment's mean removed, no padding) with its arithmetic and
    none of its checks: the same numbers to the bit, at a fraction of its cost on short series.
    """
    window = hann_window(frame)
    length = residual.shape[-1]
    if hop == frame:  # consecutive segments: a view without sliding_window_view's cost
        segments = residual[..., : length - length % frame].reshape(residual.shape[:-1] + (length // frame, frame))
    else:
        segments = np.lib.stride_tricks.sliding_window_view(residual, frame, axis=-1)[..., ::hop, :]
    magnitude = _magnitude(window * (segments - np.mean(segments, axis=-1, keepdims=True)))
    rate = 1.0 / sub_window
    times = np.arange(frame / 2, length - frame / 2 + 1, hop) / rate
    return _frequencies(frame, rate), times, np.moveaxis(magnitude, -1, -2)


def _magnitude(segments: np.ndarray) -> np.ndarray:
    """|STFT| of segments (..., frame) already detrended and windowed (float64, Hann): scipy's scale, one-sided."""
    frame = segments.shape[-1]
    spectrum = _real_fft()(segments)
    spectrum *= _stft_scale(frame)
    return np.abs(spectrum)


@cache
def _real_fft() -> Callable[[np.ndarray], np.ndarray]:
    """``scipy.fft.rfft(segments, axis=-1)`` of float64 segments: the pocketfft transform it calls (no norm,
    one worker), the same bits without its backend dispatch and checks (~7 us of ~8 on one short segment);
    where a scipy keeps it elsewhere, ``rfft`` itself."""
    try:
        from scipy.fft._pocketfft.pypocketfft import r2c
    except ImportError:
        from scipy import fft

        return partial(fft.rfft, axis=-1)
    return lambda segments: r2c(segments, (-1,), True, 0, None, 1)


@cache
def _stft_scale(frame: int) -> np.float64:
    """scipy's ``stft`` amplitude scale of a Hann window of ``frame`` samples."""
    return np.sqrt(1.0 / hann_window(frame).sum() ** 2)


@cache
def _frequencies(frame: int, rate: float) -> np.ndarray:
    """The one-sided spectrum's frequencies (Hz) of ``frame`` samples at ``rate`` Hz, read-only."""
    from scipy import fft

    frequencies = fft.rfftfreq(frame, 1 / rate)
    frequencies.flags.writeable = False
    return frequencies


def spectral_peaks(
    residual: np.ndarray, sub_window: float, scale: np.ndarray, max_frequency: float, min_relative: float = MIN_RELATIVE
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
    return _peak_table(magnitude[..., 0] / np.maximum(scale, TINY)[:, None], frequencies, max_frequency, min_relative)


def _peak_table(magnitude: np.ndarray, frequencies: np.ndarray, max_frequency: float, min_relative: float) -> np.ndarray:
    """``spectral_peaks`` of spectra (N, P) already divided by their scale."""
    out = np.empty((len(magnitude), 2 * N_PEAKS))
    tied = spectrum_peaks(magnitude, frequencies, max_frequency, min_relative, out).nonzero()[0]
    _break_ties(tied, magnitude, frequencies, max_frequency, min_relative, out)
    return out


def _break_ties(
    tied: np.ndarray, magnitude: np.ndarray, frequencies: np.ndarray, max_frequency: float, min_relative: float, out: np.ndarray
) -> None:
    """A flat top (equal neighbours) or equal peaks in the spectra (N, P) of the rows ``tied`` (indices): scipy's
    plateau rule and its sort's order decide their peaks in ``out`` (N, 2 N_PEAKS), row by row."""
    for row in tied:
        out[row] = _peaks_of(magnitude[row], frequencies, max_frequency, min_relative)


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


def frame_features(frame: Frame, variant: str, max_frequency: float = 2.0, rows: np.ndarray | None = None) -> np.ndarray:
    """Feature vectors (M, n_features) of one variant for the frames of ``rows`` (indices into the frame's
    systems; None: all of them). The frame's arrays are read in place: a frame may hold many systems.

    The strong variant's beta is the least-squares fit of the power-balance residual on the component
    powers, clipped to [-BALANCE_LIMIT, BALANCE_LIMIT]: beta_i estimates the relative deviation of
    component i's constitutive coefficient; a small ridge (``BALANCE_RIDGE``) keeps it finite when a
    component is barely excited.
    """
    if variant not in VARIANTS:
        raise ValueError(f"variant must be one of {VARIANTS}, got {variant!r}")
    rows = np.arange(len(frame.ea)) if rows is None else rows
    M, (E, F), C = len(rows), frame.ea.shape[1:], len(frame.component_index)
    # the strong variant's columns: the EA sums (3 E + C), beta (C), the noise levels, the peaks
    peak_column = 3 * E + 2 * C + frame.noise.shape[1]
    features = np.empty((M, peak_column + 2 * N_PEAKS))
    segment, reference_mean = np.empty((M, F)), np.empty(M)
    system, right_side = np.empty((M, C, C)), np.empty((M, C, 1))
    window = hann_window(F)

    def sum_rows(start: int, stop: int) -> None:
        # every element's relative residual over the frame and its halves, the components' EAI residual, the
        # I element's residual as the spectrum's one segment (spectral_peaks' arithmetic) and the balance's
        # normal equations, read in place
        part = slice(start, stop)
        frame_sums(
            frame.ea, frame.ea_reference, frame.gram, frame.cross, frame.noise, rows[part], frame.inertia_index, frame.component_index,
            window, BALANCE_RIDGE, segment[part], features[part], reference_mean[part], system[part], right_side[part],
        )

    over_rows(sum_rows, M)
    magnitude = _magnitude(segment)
    frequencies = _frequencies(F, 1.0 / frame.sub_window)
    tied = peak_and_deviation_features(
        magnitude, reference_mean, frequencies, max_frequency, MIN_RELATIVE, np.linalg.solve(system, right_side), BALANCE_LIMIT, features,
        3 * E + C, peak_column,
    )
    peaks = features[:, peak_column:]
    _break_ties(tied, magnitude, frequencies, max_frequency, MIN_RELATIVE, peaks)
    return np.ascontiguousarray(peaks) if variant == "paper" else features
