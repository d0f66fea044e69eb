"""Loads: driven node groups (:class:`Drive`, prescribed motion X + u(t)) and forces on node groups
(:class:`Force`), their reactions and work, and the energy balance H − H(0) − W (docs/loads.md)."""

from ..timefunctions import TimeFunction
from .spec import Drive, Force

__all__ = ["Drive", "Force", "TimeFunction"]
