"""femshell: growing, buckling, wrinkling thin elastic shells driven by a chemical signal.

See design.md for the model (Zakharov & Dasbiswas) and README.md for a quick start.
"""

__version__ = "0.1.0"
