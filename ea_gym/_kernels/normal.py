"""Per-system standard normal draws: row i of an array filled from generator i, in one compiled loop.

numba's ziggurat is numpy's, so the numbers are those ``Generator.standard_normal(out=row)`` gives; the
generators are passed as the addresses of their state and functions, not unboxed at every call.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable
from typing import Any, cast

import numba
import numpy as np
from numba.core import cgutils, types
from numba.extending import intrinsic
from numba.np.random.distributions import random_standard_normal

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


@numba.njit(cache=True)
def standard_normal_rows(generators: np.ndarray, out: np.ndarray) -> None:
    """Row i of ``out`` (N, ...) filled in C order from generator i (``bit_generator_addresses``, (N, 4)):
    numba's ziggurat is numpy's, so these are the numbers ``Generator.standard_normal(out=row)`` gives."""
    for i in range(out.shape[0]):
        generator = bit_generator(generators[i, 0], generators[i, 1], generators[i, 2], generators[i, 3])
        row = out[i].reshape(-1)
        for k in range(row.size):
            row[k] = random_standard_normal(generator)
