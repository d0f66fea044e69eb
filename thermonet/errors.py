"""Errors thermonet raises on purpose.

Every error a user can provoke with bad input is a :class:`ThermonetError`; its message names
the problem and where it is (file, key, node or spring index, in the user's numbering).
"""

from __future__ import annotations


class ThermonetError(Exception):
    """Base class of every error thermonet raises on purpose (the CLI prints one line)."""

    exit_code = 1


class InputError(ThermonetError, ValueError):
    """Bad input: a net, a parameter, an initial state or a name that cannot be used."""

    exit_code = 2


class MeshError(InputError):
    """A mesh file that cannot be turned into a spring net."""


class UnknownNameError(InputError, KeyError):
    """A model, integrator or other registered name that does not exist."""

    def __init__(self, kind: str, name: str, known):
        self.kind, self.name, self.known = kind, name, sorted(known)
        super().__init__(f"unknown {kind} {name!r}; known: {', '.join(self.known)}")

    def __str__(self) -> str:  # KeyError would quote the message
        return self.args[0]


class SimulationError(ThermonetError, RuntimeError):
    """A run that had to stop (non-physical state, solver failure); the last good state is kept."""

    exit_code = 3


class OutputError(ThermonetError):
    """Output that could not be written (a full disk, a read-only folder, ...); what was written
    before stays valid (every file is written atomically)."""

    exit_code = 4
