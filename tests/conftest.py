import os

from hypothesis import settings

settings.register_profile("ci", max_examples=60, deadline=None)
settings.register_profile("dev", max_examples=100, deadline=None)
settings.load_profile("ci" if os.environ.get("CI") else "dev")


def pytest_configure(config):
    """Fill numba's disk cache once before pytest-xdist starts its workers (tests/warm_numba.py):
    on a fresh clone each worker and each fresh process a test starts would otherwise compile
    the same kernel until one of them had cached it."""
    distributed = getattr(config.option, "numprocesses", None)
    if hasattr(config, "workerinput") or not (distributed or os.environ.get("CI")):
        return
    from swiptopt.jit import numba_available

    if numba_available():
        from tests.warm_numba import warm_all

        warm_all()
