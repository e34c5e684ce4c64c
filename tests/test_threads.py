"""Thread settings: the BLAS limit holds through nested contexts and is restored after the outermost."""

from __future__ import annotations

from threadpoolctl import threadpool_info

from ea_gym.threads import single_threaded_blas


def blas_threads() -> list[int]:
    return [pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"]


def test_nested_single_threaded_blas_holds_one_thread_until_the_outermost_exits() -> None:
    before = blas_threads()
    with single_threaded_blas():
        assert set(blas_threads()) == {1}
        with single_threaded_blas():
            assert set(blas_threads()) == {1}
        assert set(blas_threads()) == {1}  # the inner context leaves the outer's limit in place
    assert blas_threads() == before
