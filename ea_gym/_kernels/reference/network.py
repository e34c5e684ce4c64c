"""The isolation network's forward pass (``ea_gym._kernels.network``): each unit's sum its bias then the
inputs in turn, as the kernel adds them; tanh and exp are numpy's, which may differ from the compiled
ones in the last bit (equal to ~1e-15)."""

from __future__ import annotations

import numpy as np


def mlp_probabilities(
    inputs: np.ndarray, mean: np.ndarray, scale: np.ndarray, weights: tuple[np.ndarray, ...], biases: tuple[np.ndarray, ...],
    probabilities: np.ndarray,
) -> bool:
    """The softmax of the perceptron (tanh after every layer but the last) on the standardised ``inputs``
    (n, F) into ``probabilities``; whether every input is finite."""
    activation = (inputs - mean) / scale
    for layer, (weight, bias) in enumerate(zip(weights, biases, strict=True)):
        unit = np.broadcast_to(bias, (len(inputs), len(bias))).copy()
        for i in range(weight.shape[0]):
            unit += activation[:, i, None] * weight[i]
        activation = unit if layer == len(weights) - 1 else np.tanh(unit)
    exponential = np.exp(activation - activation.max(axis=1, keepdims=True))
    probabilities[:] = exponential / exponential.sum(axis=1, keepdims=True)
    return bool(np.isfinite(inputs).all())
