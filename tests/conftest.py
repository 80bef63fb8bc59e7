"""Fixtures shared by several test modules."""

import signal

import pytest

import femshell

# as the CLI does: numpy's BLAS on one thread, JAX's compiled kernels kept between test runs; in the
# reproducible mode (as `femshell run --reproducible`): the tests compare resumed runs bit for bit, and the
# xdist workers of a 2-core CI should not each start threads on both cores. Subprocesses inherit it.
femshell.configure(reproducible=True)


@pytest.fixture
def ctrl_c_raises():
    """SIGINT raises KeyboardInterrupt during the test, as in a terminal, also when pytest itself was
    started with SIGINT ignored (a background job of a shell script, e.g. ``.ci/run &``): Python then
    keeps the inherited SIG_IGN, and a test that presses Ctrl-C in-process would see nothing happen."""
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, old)
