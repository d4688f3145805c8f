"""Hydraulic components."""

from .orifices import LaminarOrifice, Orifice
from .sources import FlowInput, FlowSource, Plug, PressureInput, PressureSource, Pump, Tank
from .volumes import VolumeNode

__all__ = ["Tank", "PressureSource", "PressureInput", "FlowSource", "FlowInput", "Pump", "Plug",
           "Orifice", "LaminarOrifice", "VolumeNode"]
