"""The sparsity pattern: assembly against a dense reference, index maps against scipy."""

import numpy as np
import pytest
import scipy.sparse as sp

from metasheet.errors import ConfigError
from metasheet.fem import assembly
from metasheet.fem.assembly import SparsityPattern, element_dofs, submatrix_map, transpose_map
from metasheet.fem.meshes import box_mesh


def _tet_mesh(seed=0):
    """A small irregular tet mesh with shuffled node numbers and one unused node."""
    P, T = box_mesh((3.0, 2.0, 2.0), (3, 2, 2), jitter=0.2, seed=seed)
    perm = np.random.default_rng(seed).permutation(len(P) + 1)
    return len(P) + 1, perm[T]


def _hex_like(seed=0, m=30, n=40):
    """Random 8-node elements (distinct nodes each), as the voxel route's hexahedra."""
    rng = np.random.default_rng(seed)
    return n, np.array([rng.choice(n, 8, replace=False) for _ in range(m)])


def _dense(dofs, blocks, n_dofs):
    A = np.zeros((n_dofs, n_dofs))
    for d, Ke in zip(dofs, blocks):
        A[np.ix_(d, d)] += Ke
    return A


@pytest.mark.parametrize("mesh", [_tet_mesh, _hex_like])
def test_assembly_matches_a_dense_reference(mesh):
    n, E = mesh()
    pat = SparsityPattern.from_elements(E, n)
    rng = np.random.default_rng(1)
    k = 3 * E.shape[1]
    assert pat.n_dofs == 3 * n and pat.dofs.shape == (len(E), k) and pat.block_map.shape == (len(E), k * k)
    np.testing.assert_array_equal(pat.dofs, element_dofs(E))
    blocks = rng.normal(size=(len(E), k, k))  # non-symmetric on purpose
    A = pat.assemble(blocks)
    ref = _dense(pat.dofs, blocks, pat.n_dofs)
    np.testing.assert_allclose(A.toarray(), ref, rtol=0, atol=1e-13 * np.abs(ref).max())
    # canonical CSR: sorted, no duplicates, exactly the element couplings (as scipy's COO sum)
    coo = sp.coo_matrix((np.ones(blocks.size), (np.repeat(pat.dofs, k, axis=1).ravel(),
                                                np.tile(pat.dofs, (1, k)).ravel())), shape=A.shape).tocsr()
    coo.sum_duplicates()
    np.testing.assert_array_equal(A.indptr, coo.indptr)
    np.testing.assert_array_equal(A.indices, coo.indices)
    fe = rng.normal(size=(len(E), k))
    f_ref = np.zeros(pat.n_dofs)
    np.add.at(f_ref, pat.dofs, fe)
    np.testing.assert_allclose(pat.assemble_vector(fe), f_ref, rtol=0, atol=1e-14 * np.abs(f_ref).max())


@pytest.mark.parametrize("chunk", [1, 1 << 22])
def test_shared_blocks_by_kind_match_one_block_per_element(monkeypatch, chunk):
    """``kind`` (a few shared matrices) gives the per-element result, also in several chunks."""
    monkeypatch.setattr(assembly, "_CHUNK", chunk)
    n, E = _hex_like(seed=2)
    pat = SparsityPattern.from_elements(E, n)
    rng = np.random.default_rng(2)
    mats = rng.normal(size=(3, 24, 24))
    vecs = rng.normal(size=(3, 24, 6))
    kind = rng.integers(0, 3, len(E))
    full = pat.assemble_data(mats[kind])
    np.testing.assert_allclose(pat.assemble_data(mats, kind), full, rtol=0, atol=1e-13 * np.abs(full).max())
    F = pat.assemble_vector(vecs, kind)
    assert F.shape == (pat.n_dofs, 6)
    np.testing.assert_allclose(F, pat.assemble_vector(vecs[kind]), rtol=0, atol=1e-14 * np.abs(F).max())
    np.testing.assert_allclose(F[:, 2], pat.assemble_vector(vecs[:, :, 2], kind), rtol=0, atol=1e-14)


def test_submatrix_map_matches_scipy_slicing():
    n, E = _tet_mesh(seed=3)
    pat = SparsityPattern.from_elements(E, n)
    rng = np.random.default_rng(3)
    A = pat.assemble(rng.normal(size=(len(E), 12, 12)))
    rows = rng.choice(pat.n_dofs, 40, replace=False)  # unsorted
    cols = np.sort(rng.choice(pat.n_dofs, 25, replace=False))
    sub, take = pat.submatrix_map(rows, cols)
    ref = A[rows][:, cols]
    assert sub.shape == (40, 25) and sub.has_sorted_indices
    ref.sort_indices()
    np.testing.assert_array_equal(sub.indptr, ref.indptr)
    np.testing.assert_array_equal(sub.indices, ref.indices)
    sub.data[:] = A.data[take]
    np.testing.assert_array_equal(sub.toarray(), ref.toarray())  # a gather: exact
    sub2, take2 = submatrix_map(A, rows, cols)  # any CSR matrix, same answer
    np.testing.assert_array_equal(take2, take)
    np.testing.assert_array_equal(sub2.indices, sub.indices)


def test_transpose_map_matches_scipy_transposition():
    n, E = _tet_mesh(seed=4)
    pat = SparsityPattern.from_elements(E, n)
    A = pat.assemble(np.random.default_rng(4).normal(size=(len(E), 12, 12)))
    t = pat.transpose_map
    assert t is pat.transpose_map  # cached
    np.testing.assert_array_equal(pat.matrix(A.data[t]).toarray(), A.toarray().T)
    np.testing.assert_array_equal(transpose_map(A), t)
    one_sided = sp.csr_matrix(np.triu(np.ones((4, 4))))
    with pytest.raises(ConfigError, match="K_ff: pattern is not structurally symmetric"):
        transpose_map(one_sided, name="K_ff")


def test_matrix_shares_data_but_not_indices():
    n, E = _tet_mesh()
    pat = SparsityPattern.from_elements(E, n)
    data = np.ones(pat.nnz)
    A = pat.matrix(data)
    assert A.data is data or np.shares_memory(A.data, data)
    A.indices[:] = 0  # a caller's in-place change cannot reach the cached pattern
    assert pat.indices.max() > 0


def test_bad_elements_are_config_errors():
    with pytest.raises(ConfigError, match="elements: shape"):
        SparsityPattern.from_elements(np.zeros((0, 4), int), 4)
    with pytest.raises(ConfigError, match=r"elements: node indices span \[0, 9\], allowed \[0, 4\]"):
        SparsityPattern.from_elements(np.array([[0, 1, 2, 9]]), 5)
