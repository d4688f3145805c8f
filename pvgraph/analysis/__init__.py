"""Analysis of compiled circuits: steady states, linear models, power and energy."""

from .linearize import LinearModel, input_sensitivity, linearize, linearize_circuit
from .power import energy_balance, hydraulic_power
from .steady import OperatingPoint, steady_state

__all__ = ["OperatingPoint", "steady_state", "LinearModel", "linearize", "linearize_circuit",
           "input_sensitivity", "hydraulic_power", "energy_balance"]
