"""Parameter sweeps on Dask distributed: ``femshell sweep SPEC.toml`` (docs/guide/sweeps.md).

A spec (:mod:`.spec`) names a base scene and the scene keys varied over it; every point is an
ordinary run directory made on a Dask worker (:mod:`.point`); the client (:mod:`.driver`) keeps
the manifest and the results table (:mod:`.table`) and draws the phase diagram and contact sheet
(:mod:`.plots`). Importing this package does not import dask.
"""

from .driver import finish, run_sweep
from .spec import MEASURES, Point, SweepSpec, load_spec
from .table import read_manifest

__all__ = ["load_spec", "run_sweep", "finish", "read_manifest", "SweepSpec", "Point", "MEASURES"]
