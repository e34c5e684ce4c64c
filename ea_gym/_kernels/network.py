"""The isolation network's forward pass (``ea_gym.diagnosis.classifier``), one row at a time.

A row's numbers do not depend on the rows beside it: each unit's sum runs in one fixed order (its bias,
then the inputs in turn), so a single environment's row and the same row among 256 alarmed systems give
the same bits. A BLAS matrix product does not promise that: it picks its kernel, and with it the order
of the sums, by the batch's shape (torch's ``linear`` gives different last bits for a row alone and in a
batch).

Reference (the specification in plain numpy): ``ea_gym._kernels.reference.network``.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def mlp_probabilities(
    inputs: np.ndarray, mean: np.ndarray, scale: np.ndarray, weights: tuple[np.ndarray, ...], biases: tuple[np.ndarray, ...],
    probabilities: np.ndarray,
) -> bool:
    """The softmax of a multilayer perceptron (tanh after every layer but the last) on each row of
    ``inputs`` (n, F) standardised ((inputs - mean) / scale, (F,) each, in numpy's arithmetic), written
    to ``probabilities`` (n, out of the last layer): ``weights[l]`` is layer l's (in, out) matrix
    (torch's weight transposed), ``biases[l]`` its (out,) vector. Returns whether every input is finite.
    The GIL is released: parts of the rows may run on several threads at once."""
    layers = len(weights)
    width = inputs.shape[1]
    for layer in range(layers):
        width = max(width, weights[layer].shape[1])
    activation, unit = np.empty(width), np.empty(width)
    finite = True
    for row in range(inputs.shape[0]):
        size = inputs.shape[1]
        for i in range(size):
            finite &= np.isfinite(inputs[row, i])
            activation[i] = (inputs[row, i] - mean[i]) / scale[i]
        for layer in range(layers):
            weight, bias = weights[layer], biases[layer]
            units = weight.shape[1]
            unit[:units] = bias
            for i in range(size):  # the inputs in turn: the loop over units vectorizes, each unit's sum keeps its order
                x = activation[i]
                for j in range(units):
                    unit[j] += x * weight[i, j]
            last = layer == layers - 1
            for j in range(units):
                activation[j] = unit[j] if last else np.tanh(unit[j])
            size = units
        top = activation[0]
        for j in range(1, size):
            top = max(top, activation[j])
        total = 0.0
        for j in range(size):
            probabilities[row, j] = np.exp(activation[j] - top)
            total += probabilities[row, j]
        for j in range(size):
            probabilities[row, j] /= total
    return finite
