"""The node-level sparsity pattern of the shell's assembler against the entry-level one."""

import numpy as np
import pytest

from femshell.mesh.generators import plate
from femshell.shell import Clamped, Material, ShellModel, Symmetry, flat_rest_state
from femshell.shell.assembly import SparseAssembler


@pytest.mark.parametrize("seed", [0, 1])
def test_blocked_pattern_equals_the_entry_pattern(seed):
    """Random elements of 3-unknown and 1-unknown nodes (repeated nodes, fixed unknowns, nodes in no
    element): the same CSR pattern, positions and matrices as without the grouping."""
    rng = np.random.default_rng(seed)
    n_vertices, n_edges, m = 30, 20, 25
    element_nodes = np.concatenate([rng.integers(0, n_vertices, (m, 4)), n_vertices + rng.integers(0, n_edges, (m, 2))], 1)
    element_nodes[:, 3] = element_nodes[:, 0]                 # a boundary element's stand-in vertex
    slot = np.concatenate([np.repeat(np.arange(4), 3), [4, 5]])
    dof_node = np.concatenate([np.repeat(np.arange(n_vertices), 3), n_vertices + np.arange(n_edges)])
    first = np.searchsorted(dof_node, np.arange(n_vertices + n_edges))
    dofs = first[element_nodes[:, slot]] + np.concatenate([np.tile(np.arange(3), 4), [0, 0]])
    free = rng.random(len(dof_node)) < 0.7
    plain, blocked = SparseAssembler(dofs, free), SparseAssembler(dofs, free, nodes=(element_nodes, slot, dof_node))
    assert blocked.nnz == plain.nnz
    np.testing.assert_array_equal(blocked.indptr, plain.indptr)
    np.testing.assert_array_equal(blocked.indices, plain.indices)
    np.testing.assert_array_equal(blocked._mat_target, plain._mat_target)
    E = rng.standard_normal((m, 14, 14))
    np.testing.assert_array_equal(blocked.matrix(E).toarray(), plain.matrix(E).toarray())


@pytest.mark.parametrize("bcs", [[], [Clamped("left"), Symmetry("y", 0.0)]])
def test_shell_model_pattern_equals_the_entry_pattern(bcs):
    mesh = plate(1.0, 1.0, edge_length=0.25)
    model = ShellModel(mesh, Material(), flat_rest_state(mesh.points, mesh.triangles, 0.1), bcs)
    plain = SparseAssembler(model.element_dofs, model.free)
    np.testing.assert_array_equal(model.assembler.indptr, plain.indptr)
    np.testing.assert_array_equal(model.assembler.indices, plain.indices)
    np.testing.assert_array_equal(model.assembler._mat_target, plain._mat_target)
