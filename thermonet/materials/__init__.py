"""Continuum materials on meshes: E, α, ρ, c_v, k (and k*) of a region as spring parameters
(:mod:`.continuum`), the rigidity check (:mod:`.rigidity`), and the effective properties a net
has, measured on it (:mod:`.homogenize`, :mod:`.report`). See docs/continuum.md."""

from .continuum import CONTINUUM_KEYS, ContinuumMap, apply_continuum, is_continuum
from .rigidity import floppy_modes, require_rigid

__all__ = ["CONTINUUM_KEYS", "ContinuumMap", "apply_continuum", "is_continuum", "floppy_modes", "require_rigid"]
