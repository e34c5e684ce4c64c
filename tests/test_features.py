"""Isolation features: the batched spectral peaks equal scipy's find_peaks applied spectrum by spectrum."""

import numpy as np
from scipy.signal import find_peaks

from ea_gym.diagnosis.features import N_PEAKS, residual_spectrogram, spectral_peaks


def peaks_row_by_row(residual, sub_window, scale, max_frequency, min_relative=0.05):
    """The paper's peaks one spectrum at a time with scipy (the definition the batched version follows)."""
    frequencies, _, magnitude = residual_spectrogram(residual, sub_window, residual.shape[-1], residual.shape[-1])
    magnitude = magnitude[..., 0] / np.maximum(scale, 1e-300)[:, None]
    out = np.zeros((len(residual), 2 * N_PEAKS))
    for row, spectrum in enumerate(magnitude):
        peaks, _ = find_peaks(spectrum)
        peaks = peaks[frequencies[peaks] <= max_frequency]
        if len(peaks) == 0:
            continue
        peaks = peaks[spectrum[peaks] >= min_relative * spectrum[peaks].max()]
        best = peaks[np.argsort(spectrum[peaks])[::-1][:N_PEAKS]]
        out[row, 0 : 2 * len(best) : 2] = frequencies[best]
        out[row, 1 : 2 * len(best) : 2] = spectrum[best]
    return out


def test_spectral_peaks_equal_find_peaks_row_by_row_to_the_bit():
    rng = np.random.default_rng(3)
    frames, length, sub_window = 64, 40, 0.25
    t = np.arange(length) * sub_window
    residual = rng.normal(size=(frames, length)) * rng.uniform(0.01, 1.0, (frames, 1))
    residual[: frames // 2] += np.sin(2 * np.pi * rng.uniform(0.1, 1.8, (frames // 2, 1)) * t)  # one clear peak
    residual[5] = 0.0  # a flat spectrum: no peak
    residual[6] = np.cos(2 * np.pi * 0.5 * t)  # a plateau-free line at a bin
    residual[7, ::2], residual[7, 1::2] = 1.0, -1.0  # the Nyquist line only: above max_frequency
    residual[8] = np.repeat(rng.normal(size=length // 4), 4)  # equal neighbours in the spectrum are possible
    scale = rng.uniform(0.5, 2.0, frames)
    for max_frequency in (0.8, 2.0):
        np.testing.assert_array_equal(
            spectral_peaks(residual, sub_window, scale, max_frequency), peaks_row_by_row(residual, sub_window, scale, max_frequency)
        )


def test_spectral_peaks_break_plateaus_and_ties_as_find_peaks_does():
    rng = np.random.default_rng(4)
    residual = np.zeros((3, 16))
    residual[0] = 2.0  # detrended to zero: a flat spectrum, a plateau with no rising edge, no peak
    residual[1] = np.cos(2 * np.pi * np.arange(16) / 4) + np.cos(2 * np.pi * np.arange(16) / 8)  # two equal peaks
    residual[2] = rng.normal(size=16)
    scale = np.ones(3)
    np.testing.assert_array_equal(spectral_peaks(residual, 0.25, scale, 2.0), peaks_row_by_row(residual, 0.25, scale, 2.0))
    assert np.all(spectral_peaks(residual, 0.25, scale, 2.0)[0] == 0.0)


def test_residual_spectrogram_equals_scipy_stft_with_its_default_window_to_the_bit():
    from scipy.signal import stft

    residual = np.random.default_rng(5).normal(size=(7, 40)).cumsum(-1)
    for frame, hop in ((40, 40), (16, 8)):
        frequencies, times, magnitude = residual_spectrogram(residual, 0.25, frame, hop)
        f, t, Z = stft(residual, fs=4.0, nperseg=frame, noverlap=frame - hop, boundary=None, padded=False, detrend="constant")
        assert np.array_equal(frequencies, f) and np.array_equal(times, t)
        assert np.abs(Z).tobytes() == magnitude.tobytes()
