"""pvgraph: acausal component-graph modelling of hydraulic circuits.

Build a circuit from pvgraph.components, compile it to a DAE system, simulate it with an IDA-style
implicit solver, and address results by dotted name.
"""

from pathlib import Path as _Path

from . import _layout
from .circuit import Circuit
from .component import (Component, Hydraulic, Mechanical, Params, SignalIn, SignalOut, Variable,
                        der)
from .errors import (CircuitError, ConnectionError_, InitializationError, ParameterError,
                     PortConnectionError, PvgraphError, SolverError, StructureError)

__version__ = "0.1.0"

_layout.install(_Path(__file__).resolve().parent)

__all__ = [
    "Circuit", "Component", "Hydraulic", "Mechanical", "Params", "SignalIn", "SignalOut",
    "Variable", "der", "PvgraphError", "CircuitError", "PortConnectionError", "ConnectionError_",
    "ParameterError", "StructureError", "InitializationError", "SolverError",
]
