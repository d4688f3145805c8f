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

#: names of the analysis functions and classes also reachable as ``pvgraph.<name>`` (imported
#: when first used); ``pvgraph.simulate`` is the module :mod:`pvgraph.simulate`, callable as its
#: function
_ANALYSIS = ("steady_state", "linearize", "linearize_circuit", "sweep", "grid", "random_sample",
             "calibrate", "FitParameter", "CompiledRun", "energy_balance", "hydraulic_power")


def __getattr__(name):
    if name in _ANALYSIS:
        from . import analysis
        return getattr(analysis, name)
    if name == "simulate":
        import importlib
        return importlib.import_module(".simulate", __name__)
    raise AttributeError(f"module 'pvgraph' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_ANALYSIS) | {"simulate"})


__all__ = [
    "Circuit", "Component", "Hydraulic", "Mechanical", "Params", "SignalIn", "SignalOut",
    "Variable", "der", "PvgraphError", "CircuitError", "PortConnectionError", "ConnectionError_",
    "ParameterError", "StructureError", "InitializationError", "SolverError",
]
