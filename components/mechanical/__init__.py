"""Mechanical translational components: masses, springs, friction, stops and sources.

Port ``flange``: position ``x`` [m] and force ``f`` [N], the force the node exerts on the
component in +x (positive into the component). Two-flange components use ``a`` and ``b``.
"""

from .end_stop import EndStop
from .friction import Damper, Friction, TwoFlangeDamper
from .inputs import ForceInput, PositionInput
from .mass import LEVER_EQUIVALENT_MASS, MAIN_SPOOL_MASS, Fixed, SpoolMass
from .springs import CenteringSpring, LinearSpring, TwoFlangeSpring, TwoStageSpring

__all__ = ["SpoolMass", "Fixed", "LinearSpring", "TwoFlangeSpring", "TwoStageSpring",
           "CenteringSpring", "Friction", "Damper", "TwoFlangeDamper", "EndStop", "ForceInput",
           "PositionInput", "MAIN_SPOOL_MASS", "LEVER_EQUIVALENT_MASS"]
