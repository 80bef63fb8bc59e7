"""Hold Ctrl-C (and SIGTERM mapped to it) while a step is being committed.

A KeyboardInterrupt raised between two assignments of an accepted step leaves a state that
is half the old step and half the new one (c updated, the rest state not), or a run
directory whose step counter, frames and checkpoint disagree. So the code that commits a
step runs inside :func:`committing`: a signal there is only noted. Without an enclosing
:func:`step_scope` it is raised when the commit ends; inside one, the signal stays held
until the scope ends, so that the caller's bookkeeping of the step (its frame, its
checkpoint) is done too. Before the commit starts the step stays interruptible.

Blocks nest in any order; the outermost end raises. A block left by an error re-raises that
error (a noted signal is then dropped: the error ends the step anyway). The handlers are
swapped and restored with the signals blocked at the OS level, so a signal that arrives
meanwhile is delivered afterwards, never lost. Only the main thread receives signals;
elsewhere both blocks run unchanged.

A run installs :func:`interrupt_handler` for both signals (:func:`interruptible`): Ctrl-C's
KeyboardInterrupt, plus a note that survives when Python drops the exception (raised inside a
callback of the garbage collector, it is only printed), which :func:`raise_if_interrupted`
raises again between steps.
"""

from __future__ import annotations

import contextlib
import signal
import threading

_SIGNALS = (signal.SIGINT, signal.SIGTERM)
_depth = 0                       # open step_scope and committing blocks
_held: dict | None = None        # signal -> handler it had, while signals are held
_pending = False
_interrupted = False             # interrupt_handler ran since interruptible() installed it


def interrupt_handler(signum, frame):
    """SIGINT's and SIGTERM's handler in a run: KeyboardInterrupt, and a note that it was raised."""
    global _interrupted
    _interrupted = True
    raise KeyboardInterrupt


def run_handles_signals() -> bool:
    """Whether a run's :func:`interruptible` block is active (its handler holds SIGTERM)."""
    return signal.getsignal(signal.SIGTERM) is interrupt_handler


def raise_if_interrupted():
    """KeyboardInterrupt if a signal arrived whose exception Python dropped.

    Call it where a step begins. An exception raised in a callback of the garbage collector
    (a finalizer) is printed and dropped, so a SIGTERM that arrived there would otherwise be
    lost and the run go on to its end.
    """
    global _interrupted
    if _interrupted:
        _interrupted = False
        raise KeyboardInterrupt


def request_interrupt():
    """Stop the run of this process at its next step, as a Ctrl-C would (from any thread: a sweep's
    worker runs its point outside the main thread, where no signal arrives)."""
    global _interrupted
    _interrupted = True


def clear_interrupt():
    """Forget a requested stop that no run has taken (before a new run starts in the same process)."""
    global _interrupted
    _interrupted = False


@contextlib.contextmanager
def interruptible():
    """SIGINT and SIGTERM raise KeyboardInterrupt in the block (via :func:`interrupt_handler`).

    Nested blocks keep the outer block's handlers and note; the outermost puts the earlier
    handlers back. A signal the process ignores stays ignored (a shell starts background jobs
    with SIGINT ignored, so that Ctrl-C in the terminal leaves them running). Outside the main
    thread (no signals there) the block runs unchanged.

    >>> from femshell._interrupts import interruptible, raise_if_interrupted
    >>> with interruptible():
    ...     raise_if_interrupted()          # nothing arrived: no exception
    """
    global _interrupted
    if threading.current_thread() is not threading.main_thread() or run_handles_signals():
        yield
        return
    _interrupted = False
    with _masked():
        old = {sig: signal.signal(sig, interrupt_handler) for sig in _SIGNALS
               if signal.getsignal(sig) is not signal.SIG_IGN}
    try:
        yield
    finally:
        with _masked():
            for sig, handler in old.items():
                if handler is not None:         # None: a handler not set from Python, cannot be put back
                    signal.signal(sig, handler)


def _note(signum, frame):
    global _pending
    _pending = True


@contextlib.contextmanager
def _masked():
    """The block runs with SIGINT and SIGTERM blocked; any that arrived are delivered at its end."""
    if not hasattr(signal, "pthread_sigmask"):        # Windows: no masks, tiny windows stay open
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, _SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _hold():
    global _held, _pending
    if _held is None:
        _pending = False
        _held = {sig: signal.signal(sig, _note) for sig in _SIGNALS
                 if signal.getsignal(sig) in (signal.default_int_handler, interrupt_handler)}


def _restore() -> bool:
    """Put the held handlers back (the caller blocks the signals); whether a signal was noted."""
    global _held, _pending
    held, pending = _held or {}, _pending
    _held, _pending = None, False          # first: an interrupt between the two restores finds a clean state
    for sig, old in held.items():
        signal.signal(sig, old)
    return pending


@contextlib.contextmanager
def _counted(hold: bool):
    global _depth
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    entered = False
    try:
        with _masked():
            _depth += 1
            entered = True
            if hold:
                _hold()
        yield
    except BaseException:
        if entered:
            _leave()                       # the error ends the step: a noted signal is dropped
        raise
    if _leave():
        raise KeyboardInterrupt


def _leave() -> bool:
    """Close a block; at the outermost, put the handlers back. Whether a signal was noted."""
    global _depth
    with _masked():
        _depth -= 1
        return _depth == 0 and _restore()


def step_scope():
    """One step as the caller sees it: a signal held by a :func:`committing` inside is raised at its end.

    Outside a commit the block stays interruptible.
    """
    return _counted(hold=False)


def committing():
    """Run the block with SIGINT (and SIGTERM, where it raises KeyboardInterrupt) held back.

    >>> from femshell._interrupts import committing, step_scope
    >>> with step_scope():
    ...     with committing():
    ...         x = 1
    >>> x
    1
    """
    return _counted(hold=True)
