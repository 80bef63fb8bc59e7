"""Hold Ctrl-C (and SIGTERM mapped to it) while a step is being committed.

A KeyboardInterrupt raised between two assignments of an accepted step leaves a state that
is half the old step and half the new one (c updated, the rest state not), or a run
directory whose step counter, frames and checkpoint disagree. So the code that commits a
step runs inside :func:`committing`: a signal there is only noted. Without an enclosing
:func:`step_scope` it is raised when the commit ends; inside one, the signal stays held
until the scope ends, so that the caller's bookkeeping of the step (its frame, its
checkpoint) is done too. Before the commit starts the step stays interruptible. A second
signal while one is held raises at once: a user who presses Ctrl-C twice wants out now
(files are still written atomically).

Only the main thread receives signals; elsewhere both blocks run unchanged.
"""

from __future__ import annotations

import contextlib
import signal
import threading

_scopes = 0
_held: dict | None = None        # signal -> handler it had, while signals are held
_pending = False


def _note(signum, frame):
    global _pending
    if _pending:
        raise KeyboardInterrupt
    _pending = True


def _main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


def _release():
    global _held, _pending
    if _held is None:
        return
    for sig, old in _held.items():
        signal.signal(sig, old)
    _held = None
    if _pending:
        _pending = False
        raise KeyboardInterrupt


@contextlib.contextmanager
def step_scope():
    """One step as the caller sees it: signals held by a :func:`committing` inside are raised at its end."""
    global _scopes
    if not _main_thread():
        yield
        return
    _scopes += 1
    try:
        yield
    finally:
        _scopes -= 1
        if _scopes == 0:
            _release()


@contextlib.contextmanager
def committing():
    """Run the block with SIGINT (and SIGTERM, where it raises KeyboardInterrupt) held back.

    >>> from femshell._interrupts import committing, step_scope
    >>> with step_scope():
    ...     with committing():
    ...         x = 1
    >>> x
    1
    """
    global _held, _pending
    if not _main_thread():
        yield
        return
    if _held is None:
        _pending = False
        _held = {}
        for sig in (signal.SIGINT, signal.SIGTERM):
            if signal.getsignal(sig) is signal.default_int_handler:
                _held[sig] = signal.signal(sig, _note)
    try:
        yield
    finally:
        if _scopes == 0:
            _release()
