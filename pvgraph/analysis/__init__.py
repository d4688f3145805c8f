"""Analysis of compiled circuits: steady states, linear models, calibration, power and energy, sweeps."""

from .calibrate import CalibrationError, CalibrationResult, FitParameter, calibrate
from .linearize import LinearModel, input_sensitivity, linearize, linearize_circuit
from .power import energy_balance, hydraulic_power
from .steady import OperatingPoint, steady_state
from .sweep import (CaseResult, CompiledRun, SweepError, SweepResult, grid, random_sample, sweep,
                    sweep_system)

__all__ = ["OperatingPoint", "steady_state", "LinearModel", "linearize", "linearize_circuit",
           "input_sensitivity", "hydraulic_power", "energy_balance", "sweep", "grid",
           "random_sample", "SweepResult", "CaseResult", "SweepError", "CompiledRun", "sweep_system",
           "FitParameter", "CalibrationResult", "CalibrationError", "calibrate"]
