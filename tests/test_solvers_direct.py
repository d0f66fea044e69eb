"""The direct solver's pieces: the pattern's transposed order (SuperLU solves A x = b without
transposing), METIS's nested dissection on large nets, a factorization's worth read once per
pivot sequence, the solve on the factors' elimination tree (its blocks padded where the factors
left out exact zeros), and Newton's test of a residual at its rounding floor."""

import numpy as np
import scipy.sparse as sp

import thermonet as tn
import thermonet.solvers.direct as direct
import thermonet.solvers.pattern as pattern_module
from thermonet.solvers import BlockPattern
from thermonet.solvers.direct import ReusedLU, ReusedLUDouble, SparseLU
from thermonet.implicit.core.newton_policy import FLOOR_STALL_FACTOR, floor_stall


def lattice_pattern(cells=4, block=3):
    net = tn.lattice((cells, cells, cells), neighbours=18, jitter=0.1, seed=2)
    anchored = net.positions[:, 2] < 0.5
    return BlockPattern.build(np.asarray(net.edges), anchored, block)


def diagonally_dominant_values(p: BlockPattern, seed=0) -> np.ndarray:
    """(nnz,) values of a nonsymmetric, diagonally dominant matrix in the pattern."""
    rng = np.random.default_rng(seed)
    data = rng.uniform(-1.0, 1.0, p.nnz)
    A = p.matrix(data).tolil()
    A.setdiag(np.abs(p.matrix(data)).sum(axis=1).A.ravel() + 1.0)
    A = A.tocsr()
    A.sort_indices()
    assert np.array_equal(A.indices, p.indices) and np.array_equal(A.indptr, p.indptr)
    return A.data


def test_the_transpose_map_gives_the_transposed_values():
    p = lattice_pattern(3)
    data = np.random.default_rng(1).standard_normal(p.nnz)
    At = p.matrix(data).T.tocsr()
    At.sort_indices()
    assert np.array_equal(At.indptr, p.indptr) and np.array_equal(At.indices, p.indices)
    assert np.array_equal(data[p.transpose], At.data)


def test_splu_solves_the_matrix_itself():
    """A x = b for a nonsymmetric matrix (a transposed solve would give Aᵀ x = b)."""
    p = lattice_pattern(3)
    data = diagonally_dominant_values(p)
    b = np.random.default_rng(2).standard_normal(p.size)
    lu = SparseLU(p)
    lu.factorize(data)
    x = lu.solve(b)
    assert np.abs(p.matrix(data) @ x - b).max() <= 1e-12 * np.abs(b).max()


def test_large_nets_are_ordered_by_nested_dissection(monkeypatch):
    """At METIS_MIN_NODES free nodes or more the order is METIS's (another permutation than
    minimum degree's), and SuperLU on it solves as before."""
    mmd = lattice_pattern(5)
    monkeypatch.setattr(pattern_module, "METIS_MIN_NODES", 10)
    nd = lattice_pattern(5)
    assert not np.array_equal(nd.free_index, mmd.free_index)
    assert np.array_equal(np.sort(nd.free_index[nd.free_index >= 0]), np.arange(nd.n_free))
    data = diagonally_dominant_values(nd)
    b = np.ones(nd.size)
    lu = SparseLU(nd)
    lu.factorize(data)
    assert np.abs(nd.matrix(data) @ lu.solve(b) - b).max() <= 1e-12


def test_a_factorizations_worth_is_read_once_per_pivot_sequence(monkeypatch):
    p = lattice_pattern(3)
    calls = []
    real = direct.factorization_worth
    monkeypatch.setattr(direct, "factorization_worth", lambda lu: calls.append(1) or real(lu))
    lu = ReusedLU(p)
    lu.factorize(diagonally_dominant_values(p, 0), 1.0)
    first = lu.worth
    lu.factorize(diagonally_dominant_values(p, 1), 1.0)  # diagonal pivots both times: the same factors' structure
    assert len(calls) == 1 and lu.worth == first == real(lu._lu)
    lu._worth_of = (lu._worth_of[0][::-1].copy(), -1.0)  # another pivot sequence: read again
    lu.factorize(diagonally_dominant_values(p, 2), 1.0)
    assert len(calls) == 2 and lu.worth == first


def _floor_stall(history):
    """newton_policy.floor_stall for a solve's history of scaled residuals (the last one's)."""
    return floor_stall(history[-2], history[-3] if len(history) >= 3 else 0.0)


def test_a_residual_at_its_floor_is_converged_once_a_correction_contracts_far_less():
    # no correction before the last: the plain test (reduced less than 2×)
    assert _floor_stall([1.0, 1e-8]) == 0.5
    # a kept factorization contracting 3e-6, then 30× at the floor: the rounding's
    limit = _floor_stall([1e-1, 3e-7, 1e-8])
    assert limit == FLOOR_STALL_FACTOR * 3e-6 and 1e-8 > limit * 3e-7
    # a slow contraction before: no more permissive than 2×
    assert _floor_stall([1e-6, 5e-7, 4e-7]) == 0.5


def solves_on_one_and_two_threads(factors, b):
    """(x on one thread, x on two) of the tree solve with ``factors``; Numba's thread count restored."""
    import numba

    from thermonet.solvers.tree_solve import tree_solve

    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = tree_solve(factors, b)
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        return one, tree_solve(factors, b)
    finally:
        numba.set_num_threads(threads)


def test_the_tree_solve_gives_superlus_and_a_dense_solution(monkeypatch):
    """On a lattice's matrix in nested-dissection order (nonsymmetric, diagonally dominant: no
    pivoting), the factors cut into leaf subtrees and separators solve as SuperLU and NumPy's
    dense solve do, to round-off; serial and on two threads bit for bit the same. A kept
    factorization (splu-reuse) switches to it after TREE_AFTER_SOLVES solves; where SuperLU
    pivoted off the diagonal, it keeps SuperLU's solve."""
    from thermonet.solvers.tree_solve import tree_factors

    monkeypatch.setattr(pattern_module, "METIS_MIN_NODES", 10)
    p = lattice_pattern(6)  # 1 080 unknowns
    data = diagonally_dominant_values(p)
    A = p.matrix(data)
    rng = np.random.default_rng(1)
    b = rng.uniform(-1.0, 1.0, p.size)
    lu = SparseLU(p)
    lu.factorize(data)
    f, _ = tree_factors(lu._lu, 2)
    assert f is not None and f.separator.sum() >= 3 and (~f.separator).sum() >= 4
    widths = np.diff(f.block_start)  # (a node's three rows, and wider blocks: both product loops run)
    assert (widths == 3).any() and (widths > 3).any()
    x, two = solves_on_one_and_two_threads(f, b)
    binned_for_one, _ = tree_factors(lu._lu, 1)  # (its thread bins made for one thread)
    _, other_bins = solves_on_one_and_two_threads(binned_for_one, b)
    assert np.array_equal(two, x) and np.array_equal(other_bins, x)
    dense = np.linalg.solve(A.toarray(), b)
    scale = np.abs(dense).max()
    assert np.abs(x - lu.solve(b)).max() <= 1e-13 * scale
    assert np.abs(x - dense).max() <= 1e-13 * scale

    monkeypatch.setattr(direct, "TREE_AFTER_SOLVES", 2)
    monkeypatch.setattr(direct, "TREE_AFTER_LAID_OUT", 1)
    monkeypatch.setattr(direct, "TREE_MIN_UNKNOWNS", 0)
    monkeypatch.setattr(direct, "SINGLE_MIN_UNKNOWNS", 0)
    # kept factors in double and in single precision (the tree keeps their precision; its sums
    # are double, SuperLU's single solve's single: they agree to single's rounding)
    for kind, precision, tol in ((ReusedLUDouble, np.float64, 1e-13), (ReusedLU, np.float32, 1e-5)):
        kept = kind(p)
        kept.factorize(data, 1.0)
        xs = [kept.solve(b) for _ in range(4)]
        assert kept.tree_solves == 2 and kept.tree_copies == 1
        assert kept._tree.lower_vals.dtype == precision and kept._tree.diagonal.dtype == precision
        assert np.array_equal(xs[0], xs[1]) and np.array_equal(xs[2], xs[3])
        assert np.abs(xs[3] - xs[0]).max() <= tol * scale
        assert np.abs(xs[3] - dense).max() <= tol * scale
        layout = kept._layout
        assert kept.laid_out and kept.tree_layouts == 1
        other = diagonally_dominant_values(p, seed=5)  # a new factorization starts on SuperLU's solve again,
        kept.factorize(other, 1.0)  # for TREE_AFTER_LAID_OUT solves, and its copy onto the tree
        xs = [kept.solve(b) for _ in range(3)]  # reuses the layout of the same pattern
        assert kept.tree_solves == 4 and kept.tree_copies == 2 and kept._layout is layout and kept.tree_layouts == 1
        direct_x = np.linalg.solve(p.matrix(other).toarray(), b)
        assert np.abs(xs[2] - direct_x).max() <= tol * np.abs(direct_x).max()
        fresh, _ = tree_factors(kept._lu, 2)  # (the same arrays as a copy made from scratch)
        assert np.array_equal(fresh.lower_vals, kept._tree.lower_vals)
        assert np.array_equal(fresh.upper_vals, kept._tree.upper_vals)
        assert np.array_equal(fresh.diagonal, kept._tree.diagonal)

    swapped = data.copy()  # a zero diagonal entry: SuperLU swaps rows, the tree solve steps aside
    swapped[p.node_base[0]] = 0.0
    pivoted = SparseLU(p)
    pivoted.factorize(swapped)
    assert not np.array_equal(pivoted._lu.perm_r, np.arange(p.size))
    assert tree_factors(pivoted._lu, 2) == (None, None)


def test_kept_factorizations_go_on_the_tree_once_the_runs_solves_pay_for_the_first_layout(monkeypatch):
    """The switch onto the elimination tree (solvers.direct.TREE_AFTER_SOLVES,
    TREE_AFTER_LAID_OUT): SuperLU's solves count toward the first layout over all the kept
    factorizations, not each one's alone; once laid out, every later factorization goes on the
    tree after TREE_AFTER_LAID_OUT solves by the kept layout; a factorization the tree refuses
    (SuperLU pivoted off the diagonal) starts the count again."""
    monkeypatch.setattr(pattern_module, "METIS_MIN_NODES", 10)
    monkeypatch.setattr(direct, "TREE_AFTER_SOLVES", 5)
    monkeypatch.setattr(direct, "TREE_AFTER_LAID_OUT", 2)
    monkeypatch.setattr(direct, "TREE_MIN_UNKNOWNS", 0)
    p = lattice_pattern(6)
    data, other = diagonally_dominant_values(p), diagonally_dominant_values(p, seed=5)
    b = np.random.default_rng(1).uniform(-1.0, 1.0, p.size)
    kept = ReusedLUDouble(p)

    def solves(values, count):
        kept.factorize(values, 1.0)
        before = kept.tree_solves
        for _ in range(count):
            kept.solve(b)
        return kept.tree_solves - before

    assert solves(data, 3) == 0 and kept.superlu_solves == 3 and not kept.laid_out
    assert kept.solves_before_tree == 5
    assert solves(other, 3) == 1  # (2 more SuperLU solves make 5: the third is on the tree)
    assert kept.laid_out and kept.tree_layouts == 1 and kept.superlu_solves == 5
    assert solves(data, 4) == 2 and kept.tree_copies == 2 and kept.tree_layouts == 1  # (by the kept layout)
    swapped = data.copy()  # a zero diagonal entry: SuperLU swaps rows, the tree refuses the factors
    swapped[p.node_base[0]] = 0.0
    assert solves(swapped, 4) == 0 and not kept.laid_out and kept.superlu_solves == 2
    assert solves(data, 4) == 1 and kept.laid_out  # (3 more make 5)


def test_exact_zeros_in_the_factors_do_not_split_a_nodes_rows(monkeypatch):
    """SuperLU's factors leave out entries that come out exactly 0 (a net at rest has such
    Jacobian entries), so a node's three rows of L differ by a few columns; the tree pads them
    back into one block (zeros stored) rather than solving them row by row on the slow path.
    The solve stays the dense one's to round-off, the same bits on one and two threads."""
    import thermonet.solvers.tree_solve as tree_module
    from thermonet.solvers.tree_solve import tree_factors, tree_solve

    monkeypatch.setattr(pattern_module, "METIS_MIN_NODES", 10)
    p = lattice_pattern(6)
    data = diagonally_dominant_values(p)
    numbers = p.matrix(np.arange(1.0, p.nnz + 1.0)).tocoo()
    between_nodes = (numbers.data[numbers.row // 3 != numbers.col // 3] - 1).astype(int)
    rng = np.random.default_rng(3)
    data[between_nodes[rng.uniform(size=between_nodes.size) < 0.3]] = 0.0
    lu = SparseLU(p)
    lu.factorize(data)
    full = SparseLU(p)
    full.factorize(diagonally_dominant_values(p))
    assert lu._lu.L.nnz < full._lu.L.nnz  # (entries left out)

    def width3_share(f):
        widths = np.diff(f.block_start)
        entries = widths * np.diff(f.lower_ptr)[f.block_start[:-1]]
        return entries[widths == 3].sum() / entries.sum()

    f, _ = tree_factors(lu._lu, 2)
    with monkeypatch.context() as m:
        m.setattr(tree_module, "AMALGAMATION_SLACK", 1.0)  # (no padding)
        split, _ = tree_factors(lu._lu, 2)
    assert width3_share(split) < 0.6 and width3_share(f) > 0.95
    assert len(f.lower_vals) <= 1.05 * (lu._lu.L.nnz - p.size)
    b = np.random.default_rng(1).uniform(-1.0, 1.0, p.size)
    x, two = solves_on_one_and_two_threads(f, b)
    assert np.array_equal(two, x)
    dense = np.linalg.solve(p.matrix(data).toarray(), b)
    assert np.abs(x - dense).max() <= 1e-13 * np.abs(dense).max()
    assert np.abs(tree_solve(split, b) - dense).max() <= 1e-13 * np.abs(dense).max()


def test_kept_factors_are_single_and_checked_against_the_double_matrix(monkeypatch):
    """splu-reuse keeps float32 factors: their first solve is checked against the double matrix
    (a linear residual within SINGLE_MAX_LINEAR_RESIDUAL of the right-hand side), and later
    solves with them contract like single precision. Where the check fails, the same matrix is
    factorized in double, the solve is double's to round-off, and every later factorization is
    double, with the reason kept. Small matrices are factorized in double."""
    assert ReusedLU(lattice_pattern(4)).precision == "double"  # (fewer than SINGLE_MIN_UNKNOWNS unknowns)
    monkeypatch.setattr(direct, "SINGLE_MIN_UNKNOWNS", 0)
    p = lattice_pattern(4)
    data = diagonally_dominant_values(p)
    A = p.matrix(data)
    b = np.random.default_rng(3).uniform(-1.0, 1.0, p.size)
    exact = np.linalg.solve(A.toarray(), b)
    scale = np.abs(exact).max()

    single = ReusedLU(p)
    single.factorize(data, 1.0)
    assert single.precision == "single" and single._lu.L.dtype == np.float32
    x = single.solve(b)
    assert x.dtype == np.float64
    assert 1e-12 * scale < np.abs(x - exact).max() <= 1e-5 * scale  # (single's rounding, not double's)
    assert single._matrix is None and single.raised == ""  # (checked, then dropped)
    # the right-hand side's scale does not reach float32's range limits (scaled by a power of two)
    for factor in (1e-40, 1e40):
        assert np.abs(single.solve(factor * b) / factor - exact).max() <= 1e-5 * scale

    monkeypatch.setattr(direct, "SINGLE_MAX_LINEAR_RESIDUAL", 1e-12)
    raised = ReusedLU(p)
    raised.factorize(data, 1.0)
    x = raised.solve(b)
    assert raised.precision == "double" and raised._lu.L.dtype == np.float64
    assert "linear residual" in raised.raised
    assert np.abs(x - exact).max() <= 1e-13 * scale
    raised.factorize(diagonally_dominant_values(p, seed=4), 1.0)
    assert raised._lu.L.dtype == np.float64 and not raised._check

    double = ReusedLUDouble(p)
    double.factorize(data, 1.0)
    assert double.precision == "double" and double._lu.L.dtype == np.float64
    assert np.array_equal(double.solve(b), _splu_solution(p, data, b))


def _splu_solution(p, data, b):
    lu = SparseLU(p)
    lu.factorize(data)
    return lu.solve(b)


class _ScriptedProblem:
    """A Newton problem whose max |R| follows a script (scale 1: the scaled residual is max |R|)."""

    def __init__(self, script, floor):
        self.script = list(script)
        self.residual_floor = floor
        self.h = 1.0
        self.data = np.zeros(1)
        self.R = np.zeros(1)
        self.Rabs = np.ones(1)
        self.norms = None

    def residual(self, u):
        self.norms = (self.script.pop(0), 1.0)
        return 0, -1

    def jacobian(self, data):
        pass


class _KeptFactors:
    """A solver keeping one factorization (modified Newton), of single or double precision."""

    reuses_factorization = True
    assembled = True

    def __init__(self, single):
        self.single_factors = single
        self.stale = True

    def factorize(self, data, h=None):
        self.stale = False

    def usable(self, h, rho, below):
        return not self.stale

    def judged_by_cost(self):
        return True

    def contraction_limit(self, rho, tolerance, least):
        return 0.9

    def solve(self, rhs, target=0.0, settled=0.0):
        return np.ones_like(rhs)  # (a correction of 1: never at the unknowns' round-off)


def test_a_residual_a_single_precision_correction_brings_to_its_floor_is_converged():
    """Single factors contract the residual about 1e-4 per correction whatever its size: a
    residual they bring under the rounding floor while still falling at that rate is converged
    (two corrections from 1e-1: 1e-5, 1e-9 under a floor of 5e-9); double factors, whose fall at
    the floor is the error's, confirm it with a third correction, as before."""
    from thermonet.implicit.core.newton import NewtonOptions, NewtonTimers, newton

    script = [1e-1, 1e-5, 1e-9, 1e-10, 1e-10]
    for single, corrections in ((True, 2), (False, 3)):
        result = newton(_ScriptedProblem(script, 5e-9), np.zeros(1), NewtonOptions(), _KeptFactors(single),
                        NewtonTimers())
        assert result.converged and result.iterations == corrections, (single, result)
        assert result.history == script[:corrections + 1]
