"""What the distributed step carries, and a one-line refusal naming each effect it does not."""

from __future__ import annotations

from ..errors import InputError


def refusal(sim, size: int) -> str | None:
    """Why ``sim`` cannot run over ``size`` processes (the first unsupported effect), or None.

    Carried: the explicit splittings on the CPU backend, with or without thermal coupling,
    gravity, anchors, loads, heat conduction with baths and sources (multirate too). Not yet:
    the rest, each named.
    """
    system, integrator = sim.system, sim.integrator
    heat = system.heat
    unsupported = [
        (sim.backend != "cpu", f"backend {sim.backend!r} (the GPU backend runs one net per process)"),
        (not integrator.explicit, f"the implicit integrator {integrator.name!r} (use an explicit one: co2, omf4, "
                                  "bm6, ...)"),
        (heat is not None and heat.conduction and system.loads is not None,
         "heat conduction together with loads (drives, forces)"),
        (heat is not None and getattr(heat, "waves", False), "thermal waves (g_star)"),
        (bool(getattr(integrator, "subflows", ())), "extra sub-flows in the integrator's schedule"),
    ]
    for unsupported_here, effect in unsupported:
        if unsupported_here:
            return (f"a run over {size} MPI processes does not support {effect} yet; run it in one process "
                    f"(without mpiexec), or see docs/parallel.md")
    return None


def check_support(sim, size: int) -> None:
    """Raise an :class:`~thermonet.errors.InputError` naming the first effect of ``sim`` the
    distributed step does not carry."""
    why = refusal(sim, size)
    if why is not None:
        raise InputError(why)
