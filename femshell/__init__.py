"""femshell: growing, buckling, wrinkling thin elastic shells driven by a chemical signal.

The model (Zakharov & Dasbiswas) and its discretisation are in docs/theory.md; README.md has
a quick start. The modules are imported on first use, so ``import femshell`` is cheap and
``femshell.growth.contractility(0.1)`` works after it:

>>> import femshell
>>> round(float(femshell.growth.contractility(0.1)), 2)      # Λ(c*) = (Λmax + Λmin)/2
12.5
"""

import importlib
import os

# numpy's own BLAS (OpenBLAS) on one thread, unless the environment says otherwise. Its vector
# products (the quasi-Newton recursion, norms) gain nothing from threads, and its idle worker
# spins for about 0.1 s after each, taking a core from the PARDISO solve or the element kernels
# that follow: at 25k vertices a quasi-Newton solve took 0.12 s instead of 0.07 s and an energy
# with gradient 0.126 s instead of 0.099 s (2 idle cores, measured). It must be set before numpy
# is loaded; where numpy was imported before femshell it has no effect.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

__version__ = "0.1.0"

_MODULES = ("analysis", "chemistry", "cli", "coupled", "geometry", "growth", "io", "linear_buckling", "mesh",
            "scene", "shell", "solvers", "validation", "viz")


def __getattr__(name):
    if name in _MODULES:
        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module 'femshell' has no attribute {name!r}")


def __dir__():
    return sorted([*globals(), *_MODULES])
