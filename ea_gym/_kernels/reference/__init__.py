"""The specification of every compiled kernel, in plain numpy.

**The rule.** For the kernel ``ea_gym._kernels.<module>.<name>``, ``ea_gym._kernels.reference.<module>.<name>``
is a plain-numpy function with the same signature and the same effect: the same return value, the same
arrays written. It says what the kernel computes in numpy's own operations, in numpy's order where the
kernel promises numpy's bits (a sum as ``np.sum`` adds it, a clip as ``np.clip`` takes it), and it is
meant to be read: the kernels' loops, lanes and blocks are how the arithmetic runs fast, not what it is.
Each module's docstring says whether its kernels meet it to the bit or to a stated tolerance (where the
kernel sums in another order: SIMD partial sums, running moments, a filter bank's lanes); ``tests/
test_kernel_references.py`` holds every kernel against its reference on inputs that reach its branches.

Workspaces a kernel takes (``scratch``, ``basis``, ``T``) are accepted and unused; the sizes the tracking
kernels take as tuple lengths (``states``, ``inputs``) likewise.

**Exempt** (``EXEMPT``, with the reason): a compiled function that is numpy's arithmetic itself, an
inner step inlined into one kernel and specified by that kernel's reference, or one whose inputs numpy
cannot take.

**Modules**, by the stage they serve:

- plant: ``expm`` (the matrix exponential), ``propagation`` (the discretized recursion), ``rows`` (kept
  discretizations), ``multisine`` (loads), ``wear``;
- monitor: ``smoothing`` (Savitzky-Golay), ``monitor`` (a chunk's powers, EA and balances), ``activity``
  (EA and EAI), ``history``;
- chain: ``detection``, ``features``, ``network``, ``isolation``, ``tracking`` (the filter bank), ``joint`` (the joint filter),
  ``prognosis``;
- environment: ``observation``, ``ledger``;
- numpy's own sum: ``summation``.
"""

from __future__ import annotations

_INNER_TRACKING = "an inner step of tracking.track_filters' blocks of lanes, specified by reference.tracking.track_filters"
_INNER_HERMITE = "an inner step of propagation.simulate_hermite's blocks, specified by reference.propagation.simulate_hermite"
_INNER_LANES = "an inner step of smoothing.filter_lanes' running moments, specified by reference.smoothing.filter_lanes"

#: Compiled public functions of ``ea_gym._kernels`` without a reference, "module.name" -> why.
EXEMPT: dict[str, str] = {
    "numpy_forms.numpy_minimum": "np.minimum of two floats: numpy's arithmetic itself",
    "numpy_forms.numpy_maximum": "np.maximum of two floats: numpy's arithmetic itself",
    "observation.numpy_clip": "np.clip of one float: numpy's arithmetic itself",
    "activity.trapezoid_area": "one interval's trapezoid, inlined into activity's kernels and specified by their references",
    "prognosis.drift_end": "drift_ends of one parameter, inlined; specified by reference.prognosis.drift_ends",
    "summation.summation_scratch": "allocates numpy_sum's workspace: no arithmetic",
    "normal.noisy_rows": (
        "takes numpy bit generators by address, which numpy cannot take back; its numpy form is "
        "ea_gym.sensors.add_sensor_noise, held against it in tests/test_env_core_speed_semantics.py"
    ),
    "tracking.layout": "a table of row offsets (BlockRows), no arithmetic to specify",
    "tracking.at": _INNER_TRACKING,
    "tracking.positive_zero": _INNER_TRACKING,
    "tracking.parameter_fixed": _INNER_TRACKING,
    "tracking.load_lane": _INNER_TRACKING,
    "tracking.filter_samples": _INNER_TRACKING,
    "tracking.predict_states": _INNER_TRACKING,
    "tracking.propagate_covariance": _INNER_TRACKING,
    "tracking.measurement_update": _INNER_TRACKING,
    "propagation.start_block": _INNER_HERMITE,
    "propagation.load_chunk": _INNER_HERMITE,
    "propagation.hermite_block": _INNER_HERMITE,
    "propagation.step_block": _INNER_HERMITE,
    "propagation.store_chunk": _INNER_HERMITE,
    "smoothing.combine": _INNER_LANES,
    "smoothing.direct": _INNER_LANES,
    "smoothing.advance": _INNER_LANES,
    "smoothing.edges": _INNER_LANES,
}
