"""Stick-slip friction for the PVG 32 spools: the LuGre bristle model of the component library
(:class:`pvgraph.components.mechanical.LuGreFriction`), without the Stribeck dip.

On the compensator it gives the +-F_c / A dead zone of the report's Coulomb term (table 4.14:
50 N on the compensator, +-1.96 bar across its 2.545 cm^2) that the smooth
``F_c tanh(v / v_eps)`` law removes at rest (there, any force creeps the spool at
v = v_eps atanh(F / F_c)). A steady-state solve (all derivatives zero) finds no friction force:
the dead zone is a property of the history, which only a simulation reproduces.
"""

from __future__ import annotations

from pvgraph.components.mechanical.friction import LUGRE_V_EPS as V_EPS  # noqa: F401
from pvgraph.components.mechanical.friction import LuGreFriction, LuGreFrictionParams

__all__ = ["LuGreFriction", "LuGreFrictionParams"]
