"""Detection's per-step statistic and alarm (``ea_gym.phm.detection.Detector.update``) in one compiled loop.

Its sums and maxima are numpy's own (``summation``, ``numpy_forms``), so the statistic is the numpy form's to the bit;
the alarm's bookkeeping is integer and boolean.

Reference (the specification in plain numpy): ``ea_gym._kernels.reference.detection``.
"""

from __future__ import annotations

import numba
import numpy as np

from ea_gym._kernels.numpy_forms import numpy_maximum
from ea_gym._kernels.summation import numpy_sum, summation_scratch


@numba.njit(cache=True, nogil=True)
def detect(
    start: int, stop: int, ea: np.ndarray, ea_reference: np.ndarray, window: int, balance: np.ndarray, dissipated: np.ndarray,
    steps: np.ndarray, step_samples: int, span_samples: np.ndarray, thresholds: np.ndarray, persistence: int, time: np.ndarray, tiny: float,
    above: np.ndarray, alarm: np.ndarray, detection_time: np.ndarray, statistic: np.ndarray,
) -> None:
    """Systems [start, stop)'s detection statistic after their newest step, and their alarm (N systems, E
    elements); each system's alone (the GIL released: parts of the systems run on several threads).

    Args:
        ea, ea_reference: real and reference EA per sub-window (N, E, S), the last ``window`` summed.
        balance, dissipated: the energy-balance residual and the dissipators' EA per step (N, B), all summed.
        steps: updates since each system's reset (N,); step_samples: samples per update; span_samples: the
            samples each statistic needs (E + 1,), before which it is 0.
        thresholds: (E + 1,); persistence: steps in a row above one that raise the alarm; time: now (s), (N,).
        tiny: the denominators' floor.
        above, alarm, detection_time: the detection state (N,), updated in place.
        statistic: (N, E + 1) out: relative EA residual of every element, then the relative balance residual.
    """
    n_elements = ea.shape[1]
    subs = ea.shape[2]
    scratch = summation_scratch()
    for m in range(start, stop):
        seen = steps[m] * step_samples
        for e in range(n_elements + 1):
            if e < n_elements:
                real = numpy_sum(ea[m, e], subs - window, subs, scratch)
                reference = numpy_sum(ea_reference[m, e], subs - window, subs, scratch)
                value = (real - reference) / numpy_maximum(reference, tiny)
            else:
                dissipated_total = numpy_sum(dissipated[m], 0, dissipated.shape[1], scratch)
                value = numpy_sum(balance[m], 0, balance.shape[1], scratch) / numpy_maximum(dissipated_total, tiny)
            statistic[m, e] = value if seen >= span_samples[e] else 0.0
        exceeded = False
        for e in range(n_elements + 1):
            if abs(statistic[m, e]) > thresholds[e]:
                exceeded = True
        above[m] = above[m] + 1 if exceeded else 0
        if not alarm[m] and above[m] >= persistence:
            alarm[m] = True
            detection_time[m] = time[m]
