"""Every compiled kernel against its numpy reference (``ea_gym._kernels.reference``): to the bit where the
reference module says so, else to its stated tolerance, on inputs that reach the kernel's branches; and
every compiled public function of ``ea_gym._kernels`` has a reference or a documented exemption."""

from __future__ import annotations

import copy
import importlib
import pkgutil
from collections.abc import Callable
from typing import Any

import numba
import numpy as np
import pytest
from kernel_cases import CASES, Case

import ea_gym._kernels
from ea_gym._kernels.reference import EXEMPT


def compiled_functions() -> list[str]:
    """"module.name" of every public numba dispatcher defined in ``ea_gym._kernels``' modules."""
    names = []
    for info in pkgutil.iter_modules(ea_gym._kernels.__path__):
        if info.ispkg:
            continue
        module = importlib.import_module(f"ea_gym._kernels.{info.name}")
        for name, value in vars(module).items():
            if isinstance(value, numba.core.registry.CPUDispatcher) and not name.startswith("_") and value.__module__ == module.__name__:
                names.append(f"{info.name}.{name}")
    return sorted(names)


def resolve(prefix: str, name: str) -> Callable[..., Any]:
    module, function = name.rsplit(".", 1)
    return getattr(importlib.import_module(f"{prefix}.{module}"), function)


def assert_same(got: Any, want: Any, case: Case, where: str) -> None:
    """Equal to the bit (NaN and the sign of zero included) where ``case.rtol`` is None, else within tolerance."""
    if got is None or want is None:
        assert got is None and want is None, where
        return
    if isinstance(got, tuple) and not isinstance(want, np.ndarray):
        assert len(got) == len(want), where
        for k, (a, b) in enumerate(zip(got, want, strict=True)):
            assert_same(a, b, case, f"{where}[{k}]")
        return
    if isinstance(got, np.ndarray) and isinstance(want, np.ndarray):
        assert got.dtype == want.dtype, f"{where}: dtype {got.dtype} != {want.dtype}"
    got, want = np.asarray(got), np.asarray(want)
    assert got.shape == want.shape, f"{where}: shape {got.shape} != {want.shape}"
    if case.rtol is None:
        np.testing.assert_array_equal(got, want, err_msg=where, strict=False)
        if got.dtype.kind == "f":
            np.testing.assert_array_equal(np.signbit(got), np.signbit(want.astype(got.dtype)), err_msg=f"{where}: sign")
    else:
        np.testing.assert_allclose(got, want, rtol=case.rtol, atol=case.atol, err_msg=where)


@pytest.mark.parametrize("name", sorted(CASES))
def test_kernel_equals_its_reference(name: str) -> None:
    case = CASES[name](np.random.default_rng(sum(map(ord, name))))
    kernel_args, reference_args = copy.deepcopy(case.args), copy.deepcopy(case.args)
    got = resolve("ea_gym._kernels", name)(*kernel_args)
    want = resolve("ea_gym._kernels.reference", name)(*reference_args)
    assert_same(got, want, case, "returned")
    for k, (a, b) in enumerate(zip(kernel_args, reference_args, strict=True)):
        if k not in case.workspaces:
            assert_same(a, b, case, f"argument {k}")
    case.check(got, kernel_args)


def has_reference(name: str) -> bool:
    module, function = name.split(".")
    try:
        reference = importlib.import_module(f"ea_gym._kernels.reference.{module}")
    except ModuleNotFoundError:
        return False
    return callable(getattr(reference, function, None))


def test_every_compiled_function_has_a_reference_or_a_documented_exemption() -> None:
    compiled = compiled_functions()
    assert {"tracking.track_step", "monitor.monitor_chunk_step", "numpy_forms.numpy_minimum"} <= set(compiled)  # the enumeration finds them
    without = [name for name in compiled if name not in EXEMPT and not has_reference(name)]
    assert not without, f"compiled kernels without a reference or an exemption: {without}"
    assert all(len(reason) > 20 for reason in EXEMPT.values())
    assert set(EXEMPT) <= set(compiled), f"exemptions of no compiled function: {set(EXEMPT) - set(compiled)}"
    untested = set(compiled) - set(EXEMPT) - set(CASES)
    assert not untested, f"kernels with a reference but no case: {untested}"
