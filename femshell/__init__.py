"""femshell: growing, buckling, wrinkling thin elastic shells driven by a chemical signal.

The model (Zakharov & Dasbiswas) and its discretisation are in docs/theory.md; README.md has
a quick start. The modules are imported on first use, so ``import femshell`` is cheap and
``femshell.growth.contractility(0.1)`` works after it:

>>> import femshell
>>> round(float(femshell.growth.contractility(0.1)), 2)      # Λ(c*) = (Λmax + Λmin)/2
12.5

Importing femshell changes no process setting; :func:`femshell.configure` (called by the CLI)
sets BLAS threads and JAX's compilation cache explicitly.
"""

import importlib

from .config import configure

__version__ = "0.1.0"

_MODULES = ("analysis", "chemistry", "cli", "coupled", "geometry", "growth", "io", "linear_buckling", "mesh",
            "scene", "shell", "solvers", "validation", "viz")


def __getattr__(name):
    if name in _MODULES:
        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module 'femshell' has no attribute {name!r}")


def __dir__():
    return sorted([*globals(), *_MODULES])
