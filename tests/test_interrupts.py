"""Ctrl-C held while a step commits (femshell._interrupts)."""

import signal

import pytest

from femshell._interrupts import committing, interrupt_handler, interruptible, raise_if_interrupted, step_scope

pytestmark = pytest.mark.usefixtures("ctrl_c_raises")


def test_a_signal_in_a_commit_is_raised_at_the_end_of_the_step():
    done = []
    with pytest.raises(KeyboardInterrupt):
        with step_scope():
            with committing():
                signal.raise_signal(signal.SIGINT)
                signal.raise_signal(signal.SIGINT)        # pressed twice: still one step, one interrupt
                done.append("commit")
            done.append("bookkeeping")                # still held: the caller records the step
    assert done == ["commit", "bookkeeping"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_commit_alone_raises_at_its_end_and_nested_blocks_at_the_outermost():
    done = []
    with pytest.raises(KeyboardInterrupt):
        with committing():
            signal.raise_signal(signal.SIGINT)
            done.append("commit")
    assert done == ["commit"]
    with pytest.raises(KeyboardInterrupt):
        with committing():
            with committing():
                signal.raise_signal(signal.SIGINT)
            with step_scope():
                pass
            done.append("rest of the outer commit")
    assert done == ["commit", "rest of the outer commit"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_an_error_in_a_commit_is_not_hidden_by_a_held_signal():
    with pytest.raises(ValueError, match="the real problem"):
        with step_scope():
            with committing():
                signal.raise_signal(signal.SIGINT)
                raise ValueError("the real problem")
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    with step_scope():                                # nothing left pending
        with committing():
            pass


def test_before_the_commit_a_step_stays_interruptible():
    with pytest.raises(KeyboardInterrupt):
        with step_scope():
            signal.raise_signal(signal.SIGINT)
            pytest.fail("not interrupted")
    with step_scope():
        with committing():
            pass                                      # nothing pending: nothing raised


def test_a_ctrl_c_while_the_command_exits_prints_no_traceback():
    """A second Ctrl-C after `femshell run` had written everything hit JAX's atexit clean-up: 'Exception
    ignored in atexit callback ... KeyboardInterrupt', or death by SIGINT instead of exit code 130."""
    import subprocess
    import sys

    code = ("import atexit, os, signal, sys\n"
            "sys.argv = ['femshell', 'scenes']\n"
            "from femshell.cli import console_main\n"
            "atexit.register(lambda: os.kill(os.getpid(), signal.SIGINT))\n"
            "console_main()\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "KeyboardInterrupt" not in r.stderr, r.stderr


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")   # the point: Python drops it
def test_an_interrupt_dropped_in_a_finalizer_is_raised_at_the_next_check():
    import weakref

    class Held:
        pass

    before = signal.getsignal(signal.SIGTERM)
    with interruptible():
        assert signal.getsignal(signal.SIGTERM) is interrupt_handler
        raise_if_interrupted()                        # nothing arrived
        held = Held()
        weakref.finalize(held, signal.raise_signal, signal.SIGTERM)
        del held                                      # the KeyboardInterrupt is raised there and dropped
        with pytest.raises(KeyboardInterrupt):
            raise_if_interrupted()
        raise_if_interrupted()                        # raised once
        with interruptible():                         # nested: the same handlers
            with pytest.raises(KeyboardInterrupt):
                signal.raise_signal(signal.SIGINT)
    assert signal.getsignal(signal.SIGTERM) is before
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_signal_the_process_ignores_stays_ignored():
    # a shell starts background jobs with SIGINT ignored: Ctrl-C in the terminal must not stop them
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with interruptible():
            assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
            assert signal.getsignal(signal.SIGTERM) is interrupt_handler
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, old)
