"""The isolation frame's features (``ea_gym._kernels.features``): residuals, shares, the spectrum's segment
and peaks, and the balance regression's normal equations, in numpy's operations and order: to the bit."""

from __future__ import annotations

import numpy as np

from ea_gym.numerics import TINY


def relative(numerator: np.ndarray, denominator: np.ndarray) -> np.ndarray:
    """numerator / np.maximum(denominator, TINY)."""
    return numerator / np.maximum(denominator, TINY)


def frame_sums(
    ea: np.ndarray, ea_reference: np.ndarray, gram: np.ndarray, cross: np.ndarray, noise: np.ndarray, rows: np.ndarray, inertia: int,
    components: np.ndarray, window: np.ndarray, ridge: float, segment: np.ndarray, features: np.ndarray, scale: np.ndarray,
    system: np.ndarray, right_side: np.ndarray,
) -> None:
    """For the k-th of ``rows``: each element's relative EA residual over the frame and its halves, the
    components' EAI residual and the noise levels into features[k]; the I element's residual, mean
    removed, times ``window`` into segment[k] and its mean reference EA into scale[k]; gram + (ridge
    trace) I + TINY I into system[k] and cross into right_side[k, :, 0]."""
    E, F = ea.shape[1:]
    C = len(components)
    real, reference = ea[rows], ea_reference[rows]
    residual = real - reference
    real_total, reference_total, residual_total = real.sum(-1), reference.sum(-1), residual.sum(-1)
    half = F // 2
    features[:, :E] = relative(residual_total, reference_total)
    features[:, E : 2 * E] = relative(residual[..., :half].sum(-1), reference[..., :half].sum(-1))
    features[:, 2 * E : 3 * E] = relative(residual[..., half:].sum(-1), reference[..., half:].sum(-1))
    segment[: len(rows)] = window * (residual[:, inertia] - (residual_total[:, inertia] / F)[:, None])
    scale[: len(rows)] = reference_total[:, inertia] / F
    ea_share, reference_share = real_total[:, components], reference_total[:, components]
    features[:, 3 * E : 3 * E + C] = relative(ea_share, ea_share.sum(1, keepdims=True)) - relative(
        reference_share, reference_share.sum(1, keepdims=True)
    )
    features[:, 3 * E + 2 * C : 3 * E + 2 * C + noise.shape[1]] = noise[rows]
    identity = np.eye(C)
    trace_ridge = ridge * np.diagonal(gram[rows], axis1=1, axis2=2).sum(1)
    system[: len(rows)] = (gram[rows] + trace_ridge[:, None, None] * identity) + TINY * identity
    right_side[: len(rows), :, 0] = cross[rows]


def relative_noise(noise: np.ndarray) -> np.ndarray:
    """Each measured signal's relative noise level (N, X) from the sums of squares (N, 2, X)."""
    return np.sqrt(noise[:, 0] / np.maximum(noise[:, 1], TINY))


def spectrum_peaks(magnitude: np.ndarray, frequencies: np.ndarray, max_frequency: float, min_relative: float, out: np.ndarray) -> np.ndarray:
    """The largest peaks of every spectrum (M, P) into out[k] = [f_1, a_1, f_2, a_2, ...] (zeros where missing):
    samples above both neighbours up to ``max_frequency``, at least ``min_relative`` of the largest, ranked by
    amplitude (the lower frequency first of equal ones); which spectra hold equal neighbours or equal peaks."""
    count = out.shape[1] // 2
    tied = np.zeros(len(magnitude), dtype=np.bool_)
    out[:] = 0.0
    for k, spectrum in enumerate(magnitude):
        inner = spectrum[1:-1]
        peaks = 1 + np.flatnonzero((inner > spectrum[:-2]) & (inner > spectrum[2:]) & (frequencies[1:-1] <= max_frequency))
        top = spectrum[peaks].max() if len(peaks) else -np.inf
        kept = peaks[spectrum[peaks] >= min_relative * top]
        values = spectrum[kept]
        tied[k] = bool((spectrum[1:] == spectrum[:-1]).any()) or len(np.unique(values)) < len(values)
        best = kept[np.argsort(-values, kind="stable")][:count]
        out[k, 0 : 2 * len(best) : 2], out[k, 1 : 2 * len(best) : 2] = frequencies[best], spectrum[best]
    return tied


def peak_and_deviation_features(
    magnitude: np.ndarray, scale: np.ndarray, frequencies: np.ndarray, max_frequency: float, min_relative: float, deviation: np.ndarray,
    limit: float, features: np.ndarray, deviation_column: int, peak_column: int,
) -> np.ndarray:
    """Each spectrum divided by np.maximum(its scale, TINY), in place, its peaks to features[:, peak_column:];
    the deviations (M, C, 1) clipped to [-limit, limit] to features[:, deviation_column:]; the tied spectra."""
    magnitude /= np.maximum(scale, TINY)[:, None]
    features[:, deviation_column : deviation_column + deviation.shape[1]] = np.minimum(np.maximum(deviation[..., 0], -limit), limit)
    return np.flatnonzero(spectrum_peaks(magnitude, frequencies, max_frequency, min_relative, features[:, peak_column:]))
