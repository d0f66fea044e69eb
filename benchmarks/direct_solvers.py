"""The sparse direct solvers EM2's kept factorizations could use, on EM2's own Newton matrix of
the steel part (em2_paths.py's ``part``): SciPy's SuperLU in double precision (what
``splu-reuse-double`` runs), SuperLU's factors solved on their elimination tree
(thermonet.solvers.tree_solve, what ``splu-reuse`` switches to once a factorization has lasted)
at each ``--threads`` count, SuperLU in single precision (what ``splu-reuse`` factorizes from
1 000 unknowns) and its single factors on the tree, and, where pypardiso is installed,
MKL PARDISO at each ``--threads`` count, and where cholespy is installed CHOLMOD's Cholesky. Prints each solver's factorization and solve times (the
median of ``--rounds`` interleaved rounds, three solves a round), the nonzeros of its factors
where it reports them, and the relative residual max |A x − b| / max |b| of a solve. The tree
solve's "factorization" is the copy of SuperLU's factors onto the tree after SuperLU's
factorization: SuperLU handing its factors out, then, the first round, laying them out on the
tree (the layout, kept), the later rounds a gather per array by the kept layout (both printed
above the table).

    python benchmarks/direct_solvers.py --mesh-size 0.0012 --factor 100 --threads 1 2 --rounds 3
    python benchmarks/direct_solvers.py --quick      # the 1 954-spring part, one round (the test's)

The matrix: the Jacobian of EM2's step equations that the part's first step at h = ``--factor``
× CO2's stable step factorized and kept (at the step's predictor, from rest), in the
fill-reducing order the pattern bakes in (METIS's nested dissection on large nets); the
right-hand side: that step's last residual. SuperLU runs
with the options of thermonet.solvers.direct (NATURAL order, diagonal pivoting preferred) and is
single-threaded; PARDISO with its own METIS order, its real unsymmetric type (11), no iterative
refinement, through pypardiso's ``factorize`` (analysis and numerical factorization) and
``solve``. The matrix measures symmetric to round-off (printed); where cholespy is installed, CHOLMOD's
Cholesky factorization of its symmetric part (cholespy's own fill-reducing order) runs too.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
import warnings

import numpy as np
import scipy.sparse as sp

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)


def part_matrix(size: float, factor: float):
    """(A as CSC, b, springs) of the part at mesh size ``size`` and step ``factor`` × CO2's
    stable step: A the Newton matrix EM2 factorized first and kept (its first step's, from rest:
    the entries that are exactly 0 there are a run's too), b that step's last residual."""
    from em2_paths import part_simulation

    from thermonet.stability import stable_step

    est = stable_step(part_simulation(size, "co2", 1e-7))
    sim = part_simulation(size, "em2", factor * est["h_max"], newton_path="sparse", linear_solver="splu-reuse")
    st = sim.stepper
    solver = st.solver.inner
    kept = []
    factorize = solver.factorize

    def keep(data, *args, **kwargs):
        if not kept:
            kept.append(np.array(data, copy=True))
        return factorize(data, *args, **kwargs)

    solver.factorize = keep
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sim.run(steps=1, diagnostics_every=10**9)
    p = solver.pattern
    A = sp.csc_matrix((kept[0][p.transpose], p.indices, p.indptr), shape=(p.size, p.size))
    return A, st.R.copy(), sim.net.n_springs


def superlu(A):
    """SuperLU's factors of A with the options thermonet's kept factorizations use."""
    from thermonet.solvers.direct import _superlu

    return _superlu(A)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mesh-size", type=float, default=0.003, help="the part's gmsh size in m (0.0012: 97 958 springs)")
    ap.add_argument("--factor", type=float, default=100.0, help="h as a multiple of CO2's stable step")
    ap.add_argument("--threads", nargs="+", type=int, default=[1, 2], help="PARDISO's thread counts")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="the 1 954-spring part (mesh size 0.006 m), one round")
    args = ap.parse_args(argv)
    if args.quick:
        args.mesh_size, args.rounds = 0.006, 1
    A, b, springs = part_matrix(args.mesh_size, args.factor)
    A32, b32 = A.astype(np.float32), b.astype(np.float32)
    try:
        import pypardiso
    except ImportError:
        pypardiso = None
    try:
        import cholespy
    except ImportError:
        cholespy = None
    # the matrix measures symmetric to round-off (printed); Cholesky takes its symmetric part
    asymmetry = float(abs(A - A.T).max() / abs(A).max())
    if cholespy is not None:
        S = ((A + A.T) * 0.5).tocsc()
        S.sort_indices()
    pardiso = {}
    if pypardiso is not None:
        csr = A.tocsr()
        csr.sort_indices()
        for k in args.threads:
            solver = pypardiso.PyPardisoSolver(mtype=11)
            solver.set_iparm(1, 1)  # (our iparm values, the rest MKL's defaults)
            solver.set_iparm(2, 2)  # METIS's nested dissection
            solver.set_iparm(8, 0)  # no iterative refinement (Newton's own residual refines)
            solver.set_iparm(10, 13)
            solver.set_iparm(11, 1)
            solver.set_iparm(13, 1)
            solver.set_iparm(18, -1)  # report the factors' nonzeros
            pardiso[k] = solver
    times: dict = {}

    def timed(key, f):
        t0 = time.perf_counter()
        out = f()
        times.setdefault(key, []).append(time.perf_counter() - t0)
        return out

    import numba

    from thermonet.solvers.tree_solve import tree_factors, tree_solve

    threads_before = numba.get_num_threads()
    layout = None
    x = {}
    nnz = {}
    for _ in range(args.rounds):
        lu = timed("SuperLU double: factorization", lambda: superlu(A))
        for _ in range(3):
            x["SuperLU double"] = timed("SuperLU double: solve", lambda: lu.solve(b))
        copy = "tree: copy" if layout is not None else "tree: copy, first"
        tree, layout = timed(copy, lambda: tree_factors(lu, max(args.threads), layout))
        for k in args.threads if tree is not None else ():
            numba.set_num_threads(min(k, numba.config.NUMBA_NUM_THREADS))
            name = f"SuperLU's factors on the tree, {k} thread(s)"
            times.setdefault(f"{name}: factorization", []).append(times[copy][-1])
            for _ in range(3):
                x[name] = timed(f"{name}: solve", lambda: tree_solve(tree, b))
            nnz[name] = len(tree.lower_vals) + len(tree.upper_vals) + tree.size
            for _ in range(3):  # SuperLU's solve again, interleaved
                x["SuperLU double"] = timed("SuperLU double: solve", lambda: lu.solve(b))
        numba.set_num_threads(threads_before)
        del tree
        lu32 = timed("SuperLU single: factorization", lambda: superlu(A32))
        for _ in range(3):
            x["SuperLU single"] = timed("SuperLU single: solve", lambda: lu32.solve(b32).astype(np.float64))
        # single factors on the tree (what splu-reuse solves with once a factorization has lasted)
        tree32, layout = timed("tree single: copy", lambda: tree_factors(lu32, max(args.threads), layout))
        for k in args.threads if tree32 is not None else ():
            numba.set_num_threads(min(k, numba.config.NUMBA_NUM_THREADS))
            name = f"SuperLU's single factors on the tree, {k} thread(s)"
            times.setdefault(f"{name}: factorization", []).append(times["SuperLU single: factorization"][-1]
                                                                  + times["tree single: copy"][-1])
            for _ in range(3):
                x[name] = timed(f"{name}: solve", lambda: tree_solve(tree32, b))
            nnz[name] = len(tree32.lower_vals) + len(tree32.upper_vals) + tree32.size
            for _ in range(3):  # SuperLU's single solve again, interleaved
                x["SuperLU single"] = timed("SuperLU single: solve", lambda: lu32.solve(b32).astype(np.float64))
        numba.set_num_threads(threads_before)
        del tree32
        nnz["SuperLU double"] = nnz["SuperLU single"] = lu.L.nnz + lu.U.nnz
        if cholespy is not None:
            name = "CHOLMOD Cholesky (cholespy)"
            chol = timed(f"{name}: factorization", lambda: cholespy.CholeskySolverD(
                S.shape[0], S.indptr.astype(np.int32), S.indices.astype(np.int32), S.data, cholespy.MatrixType.CSC))

            def chol_solve():
                out = np.zeros_like(b)
                chol.solve(b.copy(), out)
                return out

            for _ in range(3):
                x[name] = timed(f"{name}: solve", chol_solve)
            nnz[name] = None  # (cholespy does not report it)
        for k, solver in pardiso.items():
            solver.libmkl.MKL_Set_Num_Threads(k)
            timed(f"PARDISO, {k} thread(s): factorization", lambda: solver.factorize(csr))
            for _ in range(3):
                x[f"PARDISO, {k} thread(s)"] = timed(f"PARDISO, {k} thread(s): solve", lambda: solver.solve(csr, b))
            nnz[f"PARDISO, {k} thread(s)"] = int(solver.get_iparm(18))
    print(f"\nEM2's Newton matrix of the part: {springs} springs, {A.shape[0]} unknowns, {A.nnz} nonzeros, "
          f"h = {args.factor:g} × CO2's stable step; load {os.getloadavg()[0]:.2f} (1-min average), "
          f"{os.cpu_count()} CPUs{'' if pypardiso else '; pypardiso not installed: no PARDISO rows'}"
          f"{'' if cholespy else '; cholespy not installed: no CHOLMOD row'}; max |A − Aᵀ| / max |A| = {asymmetry:.1e}\n")
    if "tree: copy, first" in times:
        kept = f"{1e3 * statistics.median(times['tree: copy']):.0f} ms" if "tree: copy" in times else "not measured (one round)"
        print(f"SuperLU's factors copied onto the tree (after each factorization, SuperLU handing them out included): "
              f"{1e3 * times['tree: copy, first'][0]:.0f} ms the first time (the layout made), then {kept} by the kept "
              f"layout (the tree rows' factorization column: the median over the rounds)\n")
    print("| solver | factorization ms | solve ms | nonzeros of the factors | max |A x − b| / max |b| |")
    print("|---|---:|---:|---:|---:|")
    rows = {}
    for name in x:
        fact = 1e3 * statistics.median(times[f"{name}: factorization"])
        solve = 1e3 * statistics.median(times[f"{name}: solve"])
        res = float(np.abs(A @ x[name] - b).max() / np.abs(b).max())
        rows[name] = dict(factorization_ms=fact, solve_ms=solve, nnz=nnz[name], residual=res)
        print(f"| {name} | {fact:.0f} | {solve:.1f} | {'–' if nnz[name] is None else nnz[name]} | {res:.1e} |")
    return rows


if __name__ == "__main__":
    main()
