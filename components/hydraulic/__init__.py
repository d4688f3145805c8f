"""Hydraulic components."""

from .accumulator import GasAccumulator
from .check_valve import CheckValve, PilotOperatedCheckValve
from .cylinder import Cylinder
from .directional_valves import (DirectionalValve22, DirectionalValve32, DirectionalValve42,
                                 DirectionalValve43, ServoValve)
from .flow_control import FlowControlValve, FlowDivider, ShuttleValve
from .fluid import MINERAL_OIL, CavitationWarning, Fluid
from .lines import PiLine, segmented_line
from .machines import (FixedDisplacementPump, HydraulicMotor, LoadSensingPump,
                       PressureCompensatedPump, VariableDisplacementPump)
from .orifices import LaminarOrifice, Orifice
from .pressure_valves import (CounterbalanceValve, DynamicReliefValve, PilotReliefValve,
                              PressureReducingValve, ReliefValve, SequenceValve)
from .solenoid import OnOffValve, PWMValve, TimedOnOffValve
from .sensors import FlowSensor, PressureSensor
from .sources import FlowInput, FlowSource, Plug, PressureInput, PressureSource, Pump, Tank
from .variable_orifice import VariableOrifice
from .volumes import PistonChamber, VolumeNode

__all__ = ["Fluid", "MINERAL_OIL", "CavitationWarning",
           "Tank", "PressureSource", "PressureInput", "FlowSource", "FlowInput", "Pump", "Plug",
           "Orifice", "LaminarOrifice", "VariableOrifice", "CheckValve",
           "PilotOperatedCheckValve",
           "ReliefValve", "DynamicReliefValve", "PilotReliefValve", "PressureReducingValve",
           "SequenceValve", "CounterbalanceValve", "ShuttleValve", "FlowControlValve", "FlowDivider",
           "DirectionalValve43", "DirectionalValve42", "DirectionalValve32", "DirectionalValve22",
           "ServoValve", "GasAccumulator", "PiLine", "segmented_line",
           "FixedDisplacementPump", "VariableDisplacementPump", "PressureCompensatedPump",
           "LoadSensingPump", "HydraulicMotor", "PressureSensor", "FlowSensor",
           "VolumeNode", "PistonChamber", "Cylinder", "OnOffValve", "TimedOnOffValve", "PWMValve"]
