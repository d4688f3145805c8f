"""The pvgraph exception hierarchy.

Every error names what is at fault (component, port, parameter or variable, and the time where
relevant) and, where it can, says what to do about it.
"""

from __future__ import annotations

__all__ = [
    "PvgraphError",
    "CircuitError",
    "ConnectionError_",
    "ParameterError",
    "StructureError",
    "InitializationError",
    "SolverError",
    "PlausibilityWarning",
    "StartValueWarning",
    "StructureWarning",
]


class PvgraphError(Exception):
    """Base class of every error raised by pvgraph."""


class CircuitError(PvgraphError):
    """A circuit is assembled wrongly: unknown or duplicate names, unconnected ports."""


class PortConnectionError(CircuitError):
    """Ports that cannot be joined: incompatible domains, two outputs driving one input."""


#: the former name (Python's own ConnectionError is about sockets)
ConnectionError_ = PortConnectionError


class ParameterError(PvgraphError):
    """A parameter is missing, non-finite or out of its allowed range."""


class StructureError(PvgraphError):
    """The compiled equations are unbalanced, structurally singular or of index above one."""


class InitializationError(PvgraphError):
    """No consistent initial condition or operating point could be found."""


class SolverError(PvgraphError):
    """The time integration failed (step size too small, repeated Newton or error test failure)."""

    def __init__(self, message: str, *, t: float | None = None, h: float | None = None,
                 culprits: list[str] | None = None):
        super().__init__(message)
        self.t = t
        self.h = h
        self.culprits = list(culprits or [])


class PlausibilityWarning(UserWarning):
    """A result is numerically fine but physically implausible (e.g. a pressure of 1e6 bar)."""


class StartValueWarning(UserWarning):
    """A start value given to a run was not kept: the consistent start computed another one."""


class StructureWarning(UserWarning):
    """The circuit compiles, but part of its structure limits what a run represents."""


def outside_stacklevel(inside: tuple = ()) -> int:
    """The ``stacklevel`` of :func:`warnings.warn` that points at the first caller outside
    pvgraph, the folders ``inside`` (a component library's) and pydantic's validators (the
    line of the user's code that led to the warning), counted from the caller of this
    function."""
    import os
    import sys
    skip = (os.path.dirname(os.path.abspath(__file__)) + os.sep,) + tuple(
        os.path.abspath(d).rstrip(os.sep) + os.sep for d in inside)
    frame, level = sys._getframe(1), 1
    while frame is not None and (
            os.path.abspath(frame.f_code.co_filename).startswith(skip) or
            f"{os.sep}pydantic{os.sep}" in frame.f_code.co_filename):
        frame, level = frame.f_back, level + 1
    return level
