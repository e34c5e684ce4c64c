"""Per-system sensor noise: system i's standard normal draws from generator i, scaled by its signals'
RMS, in one compiled loop (``ea_gym.sensors.SystemNoise``).

numba's ziggurat is numpy's, so the numbers are those ``Generator.standard_normal(out=row)`` gives; the
generators are passed as the addresses of their state and functions, not unboxed at every call.

No numpy reference takes generators by address (``ea_gym._kernels.reference.EXEMPT``): its numpy form
is ``ea_gym.sensors.add_sensor_noise``, which the tests hold it to.
"""

from __future__ import annotations

import ctypes
import math
from collections.abc import Callable
from typing import Any, cast

import numba
import numpy as np
from numba.core import cgutils, types
from numba.extending import intrinsic
from numba.np.random.distributions import random_standard_normal

from ea_gym._kernels.summation import numpy_sum, summation_scratch

BIT_GENERATOR_TYPE = types.NumPyRandomBitGeneratorType("bit_generator")


def _bit_generator_typing(typingctx: Any, state: Any, next_uint64: Any, next_uint32: Any, next_double: Any) -> tuple[Any, Any]:
    """numba's view of a numpy bit generator from the addresses of its state and functions: what
    passing the Generator itself gives, without unboxing it from Python at every call."""

    def codegen(context, builder, signature, args):
        proxy = cgutils.create_struct_proxy(BIT_GENERATOR_TYPE)(context, builder)
        proxy.state, proxy.fnptr_next_uint64, proxy.fnptr_next_uint32, proxy.fnptr_next_double = args
        return proxy._getvalue()

    return BIT_GENERATOR_TYPE(types.uintp, types.uintp, types.uintp, types.uintp), codegen


#: ``bit_generator(state, next_uint64, next_uint32, next_double)`` in compiled code: numba passes the
#: typing context itself, so the intrinsic's callers see this signature, not its definition's.
bit_generator = cast("Callable[[int, int, int, int], Any]", intrinsic(_bit_generator_typing))


def bit_generator_addresses(rng: np.random.Generator) -> tuple[int, int, int, int]:
    """(state, next_uint64, next_uint32, next_double) addresses of ``rng``'s bit generator, as ``bit_generator`` takes them."""
    interface = rng.bit_generator.ctypes
    functions = (interface.next_uint64, interface.next_uint32, interface.next_double)
    return (interface.state_address, *(ctypes.cast(f, ctypes.c_void_p).value for f in functions))


@numba.njit(cache=True, nogil=True, error_model="numpy")
def noisy_rows(generators: np.ndarray, clean: np.ndarray, fraction: float, noisy: np.ndarray) -> None:
    """noisy = clean + fraction x RMS x z for the systems' signals (N, nx, T), z drawn for system i's
    signals in C order from generator i (``bit_generator_addresses``, (N, 4)): ``add_sensor_noise``'s
    numbers, its RMS summed as numpy sums (pairwise) and every product and sum in its order.

    Each system draws from its own generator and its arithmetic is its own, so a batch's rows may be
    split over threads (``ea_gym.threads.over_rows``) as long as no two rows share a generator."""
    n_signals, n_samples = clean.shape[1], clean.shape[2]
    squares = np.empty(n_samples)
    scratch = summation_scratch()
    for i in range(clean.shape[0]):
        generator = bit_generator(generators[i, 0], generators[i, 1], generators[i, 2], generators[i, 3])
        for j in range(n_signals):
            for k in range(n_samples):
                noisy[i, j, k] = random_standard_normal(generator)
        for j in range(n_signals):
            for k in range(n_samples):
                squares[k] = clean[i, j, k] * clean[i, j, k]
            scale = fraction * math.sqrt(numpy_sum(squares, 0, n_samples, scratch) / n_samples)
            for k in range(n_samples):
                noisy[i, j, k] = noisy[i, j, k] * scale + clean[i, j, k]
