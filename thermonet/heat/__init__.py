"""Heat flow between springs: Fourier conduction, heat baths and sources, Green–Naghdi thermal
waves (spec-heat §1–2). :mod:`.graph` builds the coloured spring pairs, :mod:`.setup` checks a
run's heat-flow inputs, :mod:`.parameters` the transport parameters g and g*."""

from .setup import Bath, HeatSetup, Source, build_heat

__all__ = ["Bath", "Source", "HeatSetup", "build_heat"]
