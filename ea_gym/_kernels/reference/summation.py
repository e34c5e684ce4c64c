"""numpy's own sum, which ``ea_gym._kernels.summation.numpy_sum`` repeats to the bit."""

from __future__ import annotations

import numpy as np


def numpy_sum(values: np.ndarray, start: int, stop: int, scratch: object) -> float:
    """``np.sum(values[start:stop])`` of a 1-D float64 array; ``scratch``, the kernel's working space, is unused."""
    return float(np.sum(values[start:stop]))
