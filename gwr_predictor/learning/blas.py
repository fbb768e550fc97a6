"""One BLAS thread for whatever learns: a learner's products are small (thousands of rows by ~50), and
on a robot's computer other processes want the cores. With OpenBLAS's default of a thread per core, the
default predictor cost 17 ms of CPU (29 ms wall) per frame instead of 3.3 ms on a loaded 2-core machine.
So the environment (OPENBLAS_NUM_THREADS and the like) does not decide it: the node or command that runs
a learner pins it here, at run time (threadpoolctl), whatever was imported first."""

from __future__ import annotations

from threadpoolctl import threadpool_info, threadpool_limits


def single_threaded_blas() -> None:
    """Limit every BLAS library loaded in this process to one thread, from now on."""
    threadpool_limits(limits=1, user_api="blas")


def blas_threads() -> int:
    """The most threads any loaded BLAS library may use (0: none loaded)."""
    return max((int(lib["num_threads"]) for lib in threadpool_info() if lib.get("user_api") == "blas"), default=0)
