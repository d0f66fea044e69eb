"""Heat flow between springs: Fourier conduction, heat baths and sources, Green–Naghdi thermal
waves (docs/theory.md §5–6), as one slice: :mod:`.setup` checks a run's heat-flow inputs and
:mod:`.parameters` the transport parameters g and g*; :mod:`.graph` builds the conduction
sweep's order (junction blocks, coloured) and the waves' coloured spring pairs;
:mod:`.exchange` is what one junction, bath end, source or wave pair does on every target,
:mod:`.passes` the CPU's passes and :mod:`.cuda` the GPU's phases; :mod:`.multirate` chooses
the conduction cycle; :mod:`.stepper` wraps implicit steppers; :mod:`.logs` and :mod:`.fields`
turn the state's logs into diagnostics columns and output fields."""

from .setup import Bath, HeatSetup, Source, build_heat

__all__ = ["Bath", "Source", "HeatSetup", "build_heat"]
