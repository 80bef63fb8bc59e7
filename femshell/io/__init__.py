"""Results on disk: atomic files, ParaView time series, checkpoints, summary.json.

No physics and no plotting here: data flows one way, from the solvers into io and viz.

Every file is written **atomically**: the content goes to a temporary file in
the same directory (same file system), is flushed to disk, and then replaces
the target with :func:`os.replace`. A run killed at any moment leaves either
the old complete file or the new complete file, never a truncated one.
Temporary files are named ``.<name>.tmp-<pid>-<random><suffix>`` (hidden, same
extension so that format detection by extension still works) and are removed
when the writer fails.

**No NaN or infinity in a result file**: :func:`atomic_write_json`,
:func:`write_summary`, :class:`TimeSeriesWriter` and :func:`save_checkpoint`
refuse non-finite numbers with a ValueError that names the offending key or
field, e.g. ``summary.json: rows[3].value is NaN``.

Time series readable by ParaView: one
VTU file per frame, ``<name>_000042.vtu`` (meshio, binary, zlib), and a PVD
collection ``<name>.pvd`` listing ``(time, file)``; open the .pvd in ParaView.
Times are written with Python's shortest round-trip ``repr``, so the time read
back is bit-identical to the time written. A resumed run calls
:meth:`TimeSeriesWriter.truncate_after` with the checkpoint time and then
produces the same series as an uninterrupted run.

Checkpoints: one ``.npz`` file (no pickle) holding the state arrays and a JSON
header with the metadata; the previous checkpoint is kept as ``<path>.prev``.
:func:`load_checkpoint` falls back to ``.prev`` with a warning when the main
file is corrupt.

Units: whatever the caller stores (design units: lengths in cell sizes, time in 1/beta).

Example
-------
>>> import tempfile, numpy as np
>>> from femshell.mesh import SurfaceMesh
>>> from femshell.io import TimeSeriesWriter, read_pvd
>>> d = tempfile.mkdtemp()
>>> m = SurfaceMesh(np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))
>>> w = TimeSeriesWriter(d, m)
>>> _ = w.write(0.0, point_data={"c": np.zeros(3)})
>>> _ = w.write(0.5, point_data={"c": np.ones(3)})
>>> [t for t, _ in read_pvd(w.pvd_path)]
[0.0, 0.5]
"""

from .branches import write_branch_csv, write_special_points
from .checkpoints import CheckpointError, load_checkpoint, save_checkpoint
from .files import (SUMMARY_NAME, atomic_path, atomic_write, atomic_write_json, atomic_write_text, check_generated,
                    check_writable_dir, finite_or_none, replace_generated, temporary_of, to_json_safe, write_summary)
from .series import Frame, TimeSeriesWriter, find_series, read_frame, read_pvd

__all__ = [
    "atomic_path", "atomic_write", "atomic_write_text", "atomic_write_json", "check_generated", "replace_generated",
    "to_json_safe", "finite_or_none", "temporary_of", "check_writable_dir",
    "TimeSeriesWriter", "Frame", "read_pvd", "read_frame", "find_series",
    "save_checkpoint", "load_checkpoint", "CheckpointError",
    "write_summary", "SUMMARY_NAME",
    "write_branch_csv", "write_special_points",
]
