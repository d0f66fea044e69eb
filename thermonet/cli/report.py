"""Plain-text conservation summary printed at the end of a run."""

from __future__ import annotations


def format_summary(sim, scene: str, out: str | None = None) -> str:
    s = sim.conservation_summary()
    run = s.pop("_run")
    conserved = conserved_quantities(sim)
    lines = [
        f"thermonet: {scene}: {sim.net.n_nodes} nodes, {sim.net.n_springs} springs, model {sim.model.name}, "
        f"integrator {sim.integrator.name} (order {sim.integrator.order}), h = {sim.h:g}",
        f"  ran {run['steps']} steps to t = {sim.time:.6g} in {run['wall_time_s']:.3g} s "
        f"({run['steps_per_s']:.4g} steps/s, {run['spring_steps_per_s']:.4g} spring-steps/s)"
        + (f", after {run['compile_s']:.3g} s compiling kernels" if run.get("compile_s", 0) >= 0.05 else ""),
        f"  {'quantity':<15} {'initial':>17} {'max |deviation|':>16} {'relative':>10}",
    ]
    if "newton" in run:
        nw = run["newton"]
        lines.insert(2, f"  Newton ({nw['linear_solver']}): {nw['iterations_mean']:.3g} iterations/step (max "
                        f"{nw['iterations_max']})"
                        + (f" + {nw['jacobi_steps'] / max(1, nw['steps']):.3g} Jacobi steps/step" if nw.get("jacobi_steps") else "")
                        + f", final scaled residual <= {nw['residual_max']:.2e}, {nw['retried_steps']} retried steps")
    if sim.conduction_cycle:
        lines.insert(2, f"  {sim.conduction_cycle.describe()}")
    for name, v in s.items():
        flag = "" if name in conserved else "   (not conserved here)"
        lines.append(f"  {name:<15} {v['initial']:>17.15g} {v['max_deviation']:>16.3e} {v['relative']:>10.2e}{flag}")
    path = newton_path_line(run.get("newton"))
    if path:  # after the Newton line
        lines.insert(1 + next(i for i, line in enumerate(lines) if line.startswith("  Newton (")), path)
    if out:
        lines.append(f"  diagnostics written to {out}")
    return "\n".join(lines)


def newton_path_line(nw: dict | None) -> str:
    """Which Newton path ran and why, and the fraction of steps redone as substeps ("" where the
    summary does not say)."""
    if not nw or "newton_path" not in nw:
        return ""
    path = nw["linear_solver"] if nw["newton_path"] == "compiled" else f"sparse, {nw['linear_solver']}"
    return (f"  Newton path: {path} ({nw['path_reason']}); substepped steps {100 * nw['substep_fraction']:.3g} %"
            + (f", {nw['continued_steps']} steps solved by continuation in h" if nw.get("continued_steps") else "")
            + (f", {nw['tree_solves']} solves with kept factors compiled on their elimination tree"
               if nw.get("tree_solves") else "")
            + (f", {nw['factorizations']} factorizations ({nw['stale_refactorizations']} because the kept one had "
               f"grown stale)" if nw.get("stale_refactorizations") else "")
            + (f"; kept factors in {nw['factor_precision']} precision"
               + (f" ({nw['factor_precision_raised']})" if nw.get("factor_precision_raised") else "")
               if nw.get("factor_precision") and nw["newton_path"] != "compiled" else ""))


def conserved_quantities(sim) -> set[str]:
    """Which diagnostics the exact flow conserves for this net (momenta depend on anchors/gravity)."""
    names = {"energy", "entropy"}
    heat = sim.system.heat
    if heat is not None:  # heat flows: the balances hold; energy too when no heat enters or leaves
        names = {"energy_balance", "entropy_balance"} | ({"energy"} if not heat.names else set())
        if not heat.conduction:  # thermal waves alone are Hamiltonian: entropy is conserved
            names.add("entropy")
    if sim.loads is not None:  # loads: energy changes by the work; its balance holds
        return (names - {"energy"}) | {"energy_balance"}
    anchored = bool(sim.net.anchored.any())
    gravity = sim.system.gravity is not None
    if not anchored and not gravity:
        names |= {"px", "py", "pz", "Lx", "Ly", "Lz"}
    elif sim.net.anchor_point() is not None and not gravity:
        names |= {"Lx", "Ly", "Lz"}
    return names
