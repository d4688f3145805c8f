"""Hydraulic components."""

from .check_valve import CheckValve
from .cylinder import Cylinder
from .fluid import MINERAL_OIL, CavitationWarning, Fluid
from .orifices import LaminarOrifice, Orifice
from .solenoid import OnOffValve, PWMValve, TimedOnOffValve
from .sources import FlowInput, FlowSource, Plug, PressureInput, PressureSource, Pump, Tank
from .variable_orifice import VariableOrifice
from .volumes import PistonChamber, VolumeNode

__all__ = ["Fluid", "MINERAL_OIL", "CavitationWarning", "Tank", "PressureSource", "PressureInput", "FlowSource", "FlowInput", "Pump", "Plug",
           "Orifice", "LaminarOrifice", "VariableOrifice", "CheckValve", "VolumeNode",
           "PistonChamber", "Cylinder", "OnOffValve", "TimedOnOffValve", "PWMValve"]
