"""Thread settings: the BLAS limit holds through nested contexts and is restored after the outermost; the
kernels' rows split over the kernel threads, each row once."""

from __future__ import annotations

import os
import threading
import time

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from ea_gym.threads import (
    MIN_ROWS_PER_PART,
    MIN_ROWS_PER_THREAD,
    available_cores,
    kernel_threads,
    over_rows,
    set_kernel_threads,
    single_threaded_blas,
)


def blas_pools() -> list[dict]:
    return [pool for pool in threadpool_info() if pool["user_api"] == "blas"]


def blas_threads() -> list[int]:
    return [pool["num_threads"] for pool in blas_pools()]


def test_nested_single_threaded_blas_holds_one_thread_until_the_outermost_exits() -> None:
    before = blas_threads()
    with single_threaded_blas():
        assert set(blas_threads()) == {1}
        with single_threaded_blas():
            assert set(blas_threads()) == {1}
        assert set(blas_threads()) == {1}  # the inner context leaves the outer's limit in place
    assert blas_threads() == before


def test_single_threaded_blas_restores_each_setting_the_user_made_between_contexts() -> None:
    before = blas_threads()
    try:
        for threads in (2, 1, 3):  # the user's setting changes between two steps; one thread already: nothing to set
            threadpool_limits(threads, user_api="blas")
            with single_threaded_blas():
                assert set(blas_threads()) == {1}
            assert set(blas_threads()) == {threads}
        threadpool_limits({info["filepath"]: threads for info, threads in zip(blas_pools(), (1, 2))})  # each library its own
        with single_threaded_blas():
            assert set(blas_threads()) == {1}
        assert blas_threads() == [1, 2][: len(before)]
    finally:
        threadpool_limits({info["filepath"]: threads for info, threads in zip(blas_pools(), before)})
    assert blas_threads() == before


def test_over_rows_covers_every_row_once_in_parts_on_the_kernel_threads() -> None:
    rows = 4 * MIN_ROWS_PER_THREAD
    seen = np.zeros(rows, dtype=int)
    names: set[str] = set()
    lock = threading.Lock()

    def part(start: int, stop: int) -> None:
        with lock:
            seen[start:stop] += 1
            names.add(threading.current_thread().name)
        time.sleep(0.01)  # long enough that the worker takes parts too

    previous = kernel_threads()
    try:
        set_kernel_threads(2)
        over_rows(part, rows)
        assert seen.tolist() == [1] * rows
        assert threading.current_thread().name in names and any(name.startswith("ea-gym-kernel") for name in names)
        set_kernel_threads(1)
        names.clear()
        over_rows(part, rows)
        assert names == {threading.current_thread().name} and seen.tolist() == [2] * rows
    finally:
        set_kernel_threads(previous)


def test_over_rows_runs_few_rows_on_the_caller_in_one_part() -> None:
    calls: list[tuple[int, int]] = []
    previous = kernel_threads()
    try:
        set_kernel_threads(2)
        over_rows(lambda start, stop: calls.append((start, stop)), 2 * MIN_ROWS_PER_THREAD - 1)  # fewer than two threads' worth
    finally:
        set_kernel_threads(previous)
    assert calls == [(0, 2 * MIN_ROWS_PER_THREAD - 1)]


def test_over_rows_parts_are_contiguous_and_no_smaller_than_the_least_part() -> None:
    calls: list[tuple[int, int]] = []
    previous = kernel_threads()
    try:
        set_kernel_threads(2)
        over_rows(lambda start, stop: calls.append((start, stop)), 5 * MIN_ROWS_PER_PART)
    finally:
        set_kernel_threads(previous)
    bounds = sorted(calls)
    assert bounds[0][0] == 0 and bounds[-1][1] == 5 * MIN_ROWS_PER_PART and len(bounds) > 1
    assert all(a[1] == b[0] for a, b in zip(bounds, bounds[1:])) and all(stop - start >= MIN_ROWS_PER_PART for start, stop in bounds)


def test_over_rows_raises_a_parts_exception() -> None:
    def part(start: int, stop: int) -> None:
        if start > 0:
            raise ZeroDivisionError(f"rows {start}:{stop}")

    previous = kernel_threads()
    try:
        set_kernel_threads(2)
        with pytest.raises(ZeroDivisionError, match="rows"):
            over_rows(part, 2 * MIN_ROWS_PER_THREAD)
    finally:
        set_kernel_threads(previous)


@pytest.mark.parametrize("threads", [0, -1, 1.5, True])
def test_set_kernel_threads_refuses_a_non_positive_integer(threads: object) -> None:
    with pytest.raises(ValueError, match="threads must be a positive integer"):
        set_kernel_threads(threads)  # type: ignore[arg-type]


def test_available_cores_honours_omp_num_threads(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    assert available_cores() == 1
    monkeypatch.setenv("OMP_NUM_THREADS", "not a number")
    assert available_cores() == len(os.sched_getaffinity(0))
