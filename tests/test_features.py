"""Isolation features: the batched spectral peaks equal scipy's find_peaks applied spectrum by spectrum, and the
features of frames read in place equal their plain numpy definition to the bit."""

import numpy as np
import pytest
from scipy.signal import find_peaks

from ea_gym._kernels.features import relative_noise, spectrum_peaks
from ea_gym._kernels.summation import numpy_sum, summation_scratch
from ea_gym.diagnosis.features import N_PEAKS, VARIANTS, Frame, frame_features, residual_spectrogram, spectral_peaks
from ea_gym.numerics import TINY
from ea_gym.threads import MIN_ROWS_PER_THREAD, kernel_threads, set_kernel_threads


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


def features_by_definition(frame, variant, max_frequency):
    """``frame_features`` in plain numpy, all rows: the definition the compiled sums follow."""
    residual = frame.ea - frame.ea_reference
    i = frame.inertia_index
    peaks = peaks_row_by_row(residual[:, i], frame.sub_window, frame.ea_reference.mean(-1)[:, i], max_frequency)
    if variant == "paper":
        return peaks
    half = frame.ea.shape[-1] // 2
    relative = [
        residual[..., part].sum(-1) / np.maximum(frame.ea_reference[..., part].sum(-1), TINY)
        for part in (slice(None), slice(None, half), slice(half, None))
    ]
    ea_c, ref_c = frame.ea[:, frame.component_index].sum(-1), frame.ea_reference[:, frame.component_index].sum(-1)
    eai = ea_c / np.maximum(ea_c.sum(-1, keepdims=True), TINY) - ref_c / np.maximum(ref_c.sum(-1, keepdims=True), TINY)
    eye = np.eye(frame.gram.shape[-1])
    ridge = 1e-9 * np.trace(frame.gram, axis1=-2, axis2=-1)[..., None, None] * eye
    beta = np.clip(np.linalg.solve(frame.gram + ridge + TINY * eye, frame.cross[..., None])[..., 0], -1.0, 1.0)
    return np.concatenate([*relative, eai, beta, frame.noise, peaks], axis=-1)


def random_frame(rng, n, elements=4, length=200, offset=37):
    """Frames of n systems whose EA are windows on a longer array, as the chain's history holds them."""
    scale = 10.0 ** rng.uniform(-3, 3, (n, elements, 1))
    backing = rng.uniform(0.5, 1.5, (2, n, elements, 2 * length)) * scale
    backing[0, 1, 0] = 0.0  # an element with no activity: the relative residual's floor
    backing[1, 2, 2, :length] = backing[0, 2, 2, :length]  # no residual at all
    ea, reference = backing[..., offset : offset + length]
    gram = rng.normal(size=(n, 3, 5))
    gram[0] = 0.0  # no excitation: the ridge alone
    return Frame(
        ea=ea, ea_reference=reference, gram=gram @ gram.transpose(0, 2, 1), cross=rng.normal(size=(n, 3)),
        noise=rng.uniform(0, 0.1, (n, 2)), sub_window=0.25, component_index=np.array([0, 2, 3]), inertia_index=2,
    )


@pytest.mark.parametrize("variant", VARIANTS)
def test_frame_features_equal_their_numpy_definition_to_the_bit(variant):
    rng = np.random.default_rng(6)
    for length in (200, 40, 300):  # a frame of 300 sums past numpy's pairwise block of 128
        frame = random_frame(rng, 9, length=length)
        frame.ea_reference[4, frame.inertia_index] = frame.ea[4, frame.inertia_index]  # no residual: a flat spectrum (scipy's rules)
        everything = features_by_definition(frame, variant, 2.0)
        assert frame_features(frame, variant, 2.0).tobytes() == everything.tobytes()
        rows = np.array([7, 1, 4])
        assert frame_features(frame, variant, 2.0, rows).tobytes() == everything[rows].tobytes()
        assert frame_features(frame, variant, 2.0, np.array([], dtype=int)).shape == (0, everything.shape[1])


def test_frame_features_are_the_same_on_one_kernel_thread_and_on_two():
    frame = random_frame(np.random.default_rng(8), 2 * MIN_ROWS_PER_THREAD + 8)
    rows = np.arange(len(frame.ea))[::-1]
    previous = kernel_threads()
    try:
        by_threads = {}
        for threads in (1, 2):
            set_kernel_threads(threads)
            by_threads[threads] = [frame_features(frame, variant, 2.0, rows).tobytes() for variant in VARIANTS]
    finally:
        set_kernel_threads(previous)
    assert by_threads[1] == by_threads[2]


def test_numpy_sum_adds_as_numpy_does_to_the_bit():
    rng = np.random.default_rng(7)
    scratch = summation_scratch()
    for count in [*range(0, 300), 1000, 4099, 100_003]:
        values = rng.normal(size=count + 5) * 10.0 ** rng.uniform(-8, 8, count + 5)
        for start in (0, 3):
            assert np.float64(numpy_sum(values, start, start + count, scratch)).tobytes() == np.sum(values[start : start + count]).tobytes()
        strided = np.repeat(values, 2)[::2]  # every other value of a longer array: a view, not contiguous
        assert np.float64(numpy_sum(strided, 1, count, scratch)).tobytes() == np.sum(values[1:count]).tobytes()
    assert np.float64(numpy_sum(np.array([-0.0, -0.0]), 0, 2, scratch)).tobytes() == np.sum(np.array([-0.0, -0.0])).tobytes()
    assert np.float64(numpy_sum(np.array([-0.0]), 0, 1, scratch)).tobytes() == np.sum(np.array([-0.0])).tobytes()


def test_spectrum_peaks_flag_equal_neighbours_and_equal_peaks():
    frequencies = np.arange(8) * 0.5
    magnitude = np.array([
        [0, 3, 1, 2, 1, 0, 0.5, 0],  # distinct peaks 3 at 0.5 Hz, 2 at 1.5 Hz, 0.5 at 3 Hz
        [0, 3, 1, 3, 1, 0, 0, 0],  # two equal peaks
        [0, 1, 2, 2, 1, 0, 0, 0],  # a plateau
    ], dtype=float)
    out = np.empty((3, 2 * N_PEAKS))
    tied = spectrum_peaks(magnitude, frequencies, 2.0, 0.05, out)
    assert list(tied) == [False, True, True]
    np.testing.assert_array_equal(out[0], [0.5, 3, 1.5, 2, 0, 0])  # the third is above max_frequency


def test_relative_noise_is_numpys_ratio_of_the_sums():
    noise = np.random.default_rng(9).uniform(0.0, 2.0, (5, 2, 3)) ** 3
    noise[1, 1] = 0.0  # no signal: the floor
    noise[2] = 0.0
    expected = np.sqrt(noise[:, 0] / np.maximum(noise[:, 1], TINY))
    assert relative_noise(noise).tobytes() == expected.tobytes()
