"""A background thread that calls a function at a fixed interval while a block runs.

:func:`every` is the pattern of a progress heartbeat (print while gmsh meshes) and of a
watcher (look whether a sweep's task was cancelled): ``action()`` runs every ``interval``
seconds in a daemon thread until the block ends or ``action`` returns True. The block's end
stops the thread and waits for it, so nothing is called after the block.

>>> import time
>>> calls = []
>>> with every(0.01, lambda: calls.append(1)):
...     time.sleep(0.1)
>>> n = len(calls); time.sleep(0.05); len(calls) == n > 0
True
"""

from __future__ import annotations

import contextlib
import threading


@contextlib.contextmanager
def every(interval: float, action, *, name: str | None = None):
    """Call ``action()`` every ``interval`` seconds (the first after one interval) while the block runs;
    a True return ends the calls early. ``name`` names the thread."""
    done = threading.Event()

    def loop():
        while not done.wait(interval):
            if action():
                return

    th = threading.Thread(target=loop, daemon=True, name=name)
    th.start()
    try:
        yield
    finally:
        done.set()
        th.join()
