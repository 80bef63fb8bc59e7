"""Solvers: sparse linear back-ends, Newton for (stable) equilibria, arc-length continuation.

They know energies, gradients, Hessians and constraints, not which physics made them.
"""
