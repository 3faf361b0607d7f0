"""The API's fits run their small solves on one BLAS thread, restore the count after, and keep a
count the user set (pumpsim.blas)."""
import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from pumpsim.blas import BLAS_THREADS, small_solves


def blas_threads() -> list[int]:
    return [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]


@pytest.fixture
def no_user_count(monkeypatch):
    """No count in the environment, and two threads to start from (whatever the machine set)."""
    for name in BLAS_THREADS:
        monkeypatch.delenv(name, raising=False)
    np.linalg.svd(np.ones((3, 3)))  # NumPy's BLAS loaded
    with threadpool_limits(limits=2, user_api="blas"):
        yield


def test_one_thread_inside_and_the_count_restored_after(no_user_count):
    before = blas_threads()
    if not before:
        pytest.skip("no BLAS library threadpoolctl can control")
    seen = []

    @small_solves
    def inner():
        seen.append(blas_threads())
        return 7

    @small_solves
    def outer():  # an API call inside another (diagnose -> identify): one limit, restored once
        seen.append(blas_threads())
        return inner() + 1

    assert outer() == 8
    assert set(before) == {2}
    assert seen == [[1] * len(before)] * 2
    assert blas_threads() == before


def test_a_count_the_user_set_is_kept(monkeypatch):
    np.linalg.svd(np.ones((3, 3)))
    before = blas_threads()
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "2")
    assert small_solves(blas_threads)() == before


def test_the_limit_is_lifted_when_the_call_raises(no_user_count):
    before = blas_threads()

    @small_solves
    def fails():
        raise ValueError("bad key")

    with pytest.raises(ValueError, match="bad key"):
        fails()
    assert blas_threads() == before
    assert small_solves(lambda: blas_threads())() == [1] * len(before)  # and set again next time
