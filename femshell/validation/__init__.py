"""Validation cases: femshell against theory, the seed paper and classical benchmarks.

Each case is a module in this package that defines

* ``NAME`` (the command-line name, e.g. ``"patch-tests"``),
* ``DESCRIPTION`` (one line) and ``SOURCE`` (where the reference comes from),
* ``run(level: str) -> list[Row]`` with ``level`` in ``{"quick", "full"}``,
* optionally ``plot(rows, fig)`` to draw a case-specific figure (the default is
  error against vertex count and against wall time for every quantity that has a
  reference).

:func:`run_case` writes ``DIR/NAME.json`` (keys case, level, source, description, total_wall_s
and rows, one dict per :class:`Row`) and ``DIR/NAME.png``, and returns whether every row with a
tolerance passed.

Example
-------
>>> from femshell.validation import list_cases
>>> "patch-tests" in list_cases()  # doctest: +SKIP
True
"""

from .framework import CASES, Row, list_cases, run_case, timed

__all__ = ["CASES", "Row", "list_cases", "run_case", "timed"]
