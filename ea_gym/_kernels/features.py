"""The isolation features' compiled steps (``ea_gym.diagnosis.features``): a frame's EA sums and balance
system read straight from the frame's rows (no copy of the frame), and, after numpy's spectrum and
solve, the largest peaks of every spectrum and the clipped deviations.

Every sum is numpy's (:func:`~ea_gym._kernels.summation.numpy_sum`), so that the features equal the
plain numpy form of their definition to the bit.

Reference (the specification in plain numpy): ``ea_gym._kernels.reference.features``.
"""

from __future__ import annotations

import numba
import numpy as np

from ea_gym._kernels.numpy_forms import numpy_maximum, numpy_minimum
from ea_gym._kernels.summation import numpy_sum, summation_scratch
from ea_gym.numerics import TINY


@numba.njit(cache=True)
def _relative(numerator: float, denominator: float) -> float:
    """numerator / np.maximum(denominator, TINY) (NaN stays NaN)."""
    return numerator / numpy_maximum(denominator, TINY)


@numba.njit(cache=True, nogil=True)
def frame_sums(
    ea: np.ndarray, ea_reference: np.ndarray, gram: np.ndarray, cross: np.ndarray, noise: np.ndarray, rows: np.ndarray, inertia: int,
    components: np.ndarray, window: np.ndarray, ridge: float, segment: np.ndarray, features: np.ndarray, scale: np.ndarray,
    system: np.ndarray, right_side: np.ndarray,
) -> None:
    """The per-row arithmetic of the frames of ``rows`` before their spectrum and their balance regression:
    ``ea`` and ``ea_reference`` (N, E, F) in J, the balance statistics ``gram`` (N, C, C) and ``cross``
    (N, C), the relative noise levels ``noise`` (N, X).

    Writes, for the k-th row: segment[k] = the I element's residual (EA_real - EA_ref) per sub-window,
    its mean removed, times ``window`` (F,) (the spectrum's segment, as scipy's ``stft`` makes it);
    features[k, :3 E] = every element's relative residual over the frame, its first half and its
    second half (each E wide); features[k, 3 E : 3 E + C] = the components' EAI residual;
    features[k, 3 E + 2 C : 3 E + 2 C + X] = the noise levels; scale[k] = the I element's mean
    reference EA per sub-window; system[k] = gram with (``ridge`` x its trace + TINY) added on the
    diagonal, as numpy adds it (gram plus ridge trace times the identity, then TINY times the identity,
    the off-diagonal zeros added too), and right_side[k, :, 0] = cross, the normal equations of the
    balance's relative deviations. Each row's numbers are its own: the rows may be split over threads
    (the GIL released).
    """
    E, F = ea.shape[1], ea.shape[2]
    C, X = len(components), noise.shape[1]
    half = F // 2
    # the sums read the frame in place: each element's sub-windows are contiguous (a window on the history's
    # backing array), which ascontiguousarray tells the compiled loops without a copy (they then vectorise)
    residual = np.empty(F)
    real_total, reference_total = np.empty(E), np.empty(E)
    ea_share, reference_share = np.empty(C), np.empty(C)
    diagonal = np.empty(C)
    scratch = summation_scratch()
    for k in range(len(rows)):
        n = rows[k]
        for e in range(E):
            real, reference = np.ascontiguousarray(ea[n, e]), np.ascontiguousarray(ea_reference[n, e])
            for t in range(F):
                residual[t] = real[t] - reference[t]
            real_total[e] = numpy_sum(real, 0, F, scratch)
            reference_total[e] = numpy_sum(reference, 0, F, scratch)
            residual_total = numpy_sum(residual, 0, F, scratch)
            features[k, e] = _relative(residual_total, reference_total[e])
            features[k, E + e] = _relative(numpy_sum(residual, 0, half, scratch), numpy_sum(reference, 0, half, scratch))
            features[k, 2 * E + e] = _relative(numpy_sum(residual, half, F, scratch), numpy_sum(reference, half, F, scratch))
            if e == inertia:
                mean = residual_total / F
                for t in range(F):
                    segment[k, t] = window[t] * (residual[t] - mean)
                scale[k] = reference_total[e] / F
        for c in range(C):
            ea_share[c], reference_share[c] = real_total[components[c]], reference_total[components[c]]
        ea_sum, reference_sum = numpy_sum(ea_share, 0, C, scratch), numpy_sum(reference_share, 0, C, scratch)
        for c in range(C):
            features[k, 3 * E + c] = _relative(ea_share[c], ea_sum) - _relative(reference_share[c], reference_sum)
        for x in range(X):
            features[k, 3 * E + 2 * C + x] = noise[n, x]
        for c in range(C):
            diagonal[c] = gram[n, c, c]
        trace_ridge = ridge * numpy_sum(diagonal, 0, C, scratch)
        for i in range(C):
            for j in range(C):
                identity = 1.0 if i == j else 0.0
                system[k, i, j] = (gram[n, i, j] + trace_ridge * identity) + TINY * identity
            right_side[k, i, 0] = cross[n, i]


@numba.njit(cache=True)
def relative_noise(noise: np.ndarray) -> np.ndarray:
    """The relative noise level of each measured signal, (N, X), from the sums of the squares of its noise
    and of the signal (N, 2, X): np.sqrt(noise[:, 0] / np.maximum(noise[:, 1], TINY))."""
    N, X = noise.shape[0], noise.shape[2]
    level = np.empty((N, X))
    for n in range(N):
        for x in range(X):
            level[n, x] = np.sqrt(noise[n, 0, x] / numpy_maximum(noise[n, 1, x], TINY))
    return level


@numba.njit(cache=True)
def spectrum_peaks(magnitude: np.ndarray, frequencies: np.ndarray, max_frequency: float, min_relative: float, out: np.ndarray) -> np.ndarray:
    """The largest peaks of every spectrum (M, P): out[k] = [f_1, a_1, f_2, a_2, ...] (zeros where missing).

    A peak is a sample above both neighbours at a frequency up to ``max_frequency`` whose amplitude is
    at least ``min_relative`` of the largest such one; they are ranked by amplitude. Returns which
    spectra hold equal neighbours or equal peaks (M,): for those, plateaus and ties need scipy's rules.
    """
    M, P = magnitude.shape
    count = out.shape[1] // 2
    tied = np.zeros(M, dtype=np.bool_)
    peaks = np.empty(P, dtype=np.int64)
    for k in range(M):
        spectrum = magnitude[k]
        found = 0
        top = -np.inf
        for p in range(P):
            if p > 0 and spectrum[p] == spectrum[p - 1]:
                tied[k] = True
            if 0 < p < P - 1 and spectrum[p] > spectrum[p - 1] and spectrum[p] > spectrum[p + 1] and frequencies[p] <= max_frequency:
                peaks[found] = p
                found += 1
                top = max(top, spectrum[p])
        floor = min_relative * top
        out[k] = 0.0
        # the largest first; of equal ones the lower frequency (then the spectrum is tied anyway)
        best = np.full(count, -1)
        for j in range(found):
            p = peaks[j]
            value = spectrum[p]
            if not value >= floor:
                continue
            for other in range(j):
                if spectrum[peaks[other]] == value and spectrum[peaks[other]] >= floor:
                    tied[k] = True
            for slot in range(count):
                if best[slot] < 0 or value > spectrum[best[slot]]:
                    for moved in range(count - 1, slot, -1):
                        best[moved] = best[moved - 1]
                    best[slot] = p
                    break
        for slot in range(count):
            if best[slot] >= 0:
                out[k, 2 * slot] = frequencies[best[slot]]
                out[k, 2 * slot + 1] = spectrum[best[slot]]
    return tied


@numba.njit(cache=True)
def peak_and_deviation_features(
    magnitude: np.ndarray, scale: np.ndarray, frequencies: np.ndarray, max_frequency: float, min_relative: float, deviation: np.ndarray,
    limit: float, features: np.ndarray, deviation_column: int, peak_column: int,
) -> np.ndarray:
    """The features that follow the frames' spectra and balance regressions, M frames.

    Divides each spectrum ``magnitude`` (M, P) by np.maximum(its ``scale`` (M,), TINY), in place, and
    writes its largest peaks (:func:`spectrum_peaks`) to features[:, peak_column:]; writes the balance's
    relative deviations ``deviation`` (M, C, 1) clipped to [-limit, limit] (np.clip's numbers) to
    features[:, deviation_column : deviation_column + C]. Returns the spectra that need scipy's rules for
    plateaus and ties (their indices).
    """
    M, P = magnitude.shape
    C = deviation.shape[1]
    for k in range(M):
        divisor = numpy_maximum(scale[k], TINY)
        for p in range(P):
            magnitude[k, p] = magnitude[k, p] / divisor
        for c in range(C):
            features[k, deviation_column + c] = numpy_minimum(numpy_maximum(deviation[k, c, 0], -limit), limit)
    return spectrum_peaks(magnitude, frequencies, max_frequency, min_relative, features[:, peak_column:]).nonzero()[0]
