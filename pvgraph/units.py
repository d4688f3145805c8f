"""Unit helpers for the edges of the model (presets, examples, CLI).

Inside pvgraph everything is SI. These helpers convert the units hydraulic engineers quote:
``bar(13.5)`` -> Pa, ``lpm(16.3)`` -> m^3/s, ``mm(7)`` -> m, ``mm2(3.5)`` -> m^2, ``cm3(8)`` -> m^3.
Each has an inverse ``to_bar``, ``to_lpm``, ``to_mm``, ... for reporting.
"""

from __future__ import annotations

import math

BAR = 1e5
LPM = 1e-3 / 60.0
MM = 1e-3
MM2 = 1e-6
CM3 = 1e-6
LITRE = 1e-3


def bar(value):
    """Pressure in bar -> Pa."""
    return value * BAR


def to_bar(value):
    """Pressure in Pa -> bar."""
    return value / BAR


def lpm(value):
    """Flow in L/min -> m^3/s."""
    return value * LPM


def to_lpm(value):
    """Flow in m^3/s -> L/min."""
    return value / LPM


def mm(value):
    """Length in mm -> m."""
    return value * MM


def to_mm(value):
    """Length in m -> mm."""
    return value / MM


def mm2(value):
    """Area in mm^2 -> m^2."""
    return value * MM2


def to_mm2(value):
    """Area in m^2 -> mm^2."""
    return value / MM2


def cm3(value):
    """Volume in cm^3 -> m^3."""
    return value * CM3


def litre(value):
    """Volume in L -> m^3."""
    return value * LITRE


def deg(value):
    """Angle in degrees -> rad."""
    return math.radians(value)


def circle_area(diameter):
    """Area of a circle of the given diameter [m] -> [m^2]."""
    return math.pi * diameter**2 / 4.0


def lpm_per_bar(value):
    """Laminar flow constant in L/(min bar) -> m^3/(s Pa)."""
    return value * LPM / BAR
