"""Typed errors. The CLI maps each to a one-line message and exit code 2."""

from __future__ import annotations


class MarinebenchError(Exception):
    """Base class for user-facing errors (bad input, infeasible design)."""


class ConfigError(MarinebenchError):
    """A configuration problem, located by file and dotted key path."""

    def __init__(self, file: str, key: str, message: str) -> None:
        self.file, self.key, self.message = str(file), key, message
        where = f"{self.file}: {key}" if key else self.file
        super().__init__(f"{where}: {message}")


class DesignError(MarinebenchError):
    """An observer or controller design failed (e.g. an infeasible LMI)."""


class StiffnessError(MarinebenchError):
    """The integration step is too large for the designed observer poles."""


class ClusterError(MarinebenchError):
    """Dask is not installed, its scheduler cannot be reached, its workers cannot run this marinebench, or a
    chunk failed on a worker."""


class UserCodeError(MarinebenchError):
    """A class of your own (``kind: custom``) raised while the runs were simulated."""


class ProtocolError(ValueError):
    """A class of your own (``kind: custom``) answered outside its protocol: a missing or undeclared signal, an array
    of the wrong shape. At validation it is a config error; while the runs are simulated, one line (``plugins``)."""
