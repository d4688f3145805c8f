"""Mechanical components: translational masses, springs, friction, stops, sources, sensors and
transmissions, and the rotational shaft domain (inertia, shaft, torque and speed sources).

Port ``flange``: position ``x`` [m] and force ``f`` [N], the force the node exerts on the
component in +x (positive into the component). Two-flange components use ``a`` and ``b``.
"""

from .end_stop import EndStop
from .friction import Damper, Friction, LuGreFriction, TwoFlangeDamper
from .inputs import ForceInput, ForceSource, PositionInput, VelocityInput, VelocitySource
from .mass import LEVER_EQUIVALENT_MASS, MAIN_SPOOL_MASS, Fixed, Free, Mass, SpoolMass
from .rotational import (AngleSensor, Inertia, RotationalDamper, RotationalFixed,
                         RotationalFree, ShaftSpringDamper,
                         SpeedInput, SpeedSensor, SpeedSource, TorqueInput, TorqueSensor,
                         TorqueSource)
from .sensors import ForceSensor, PositionSensor, VelocitySensor
from .transmissions import Gear, Lever, RackPinion
from .springs import CenteringSpring, LinearSpring, TwoFlangeSpring, TwoStageSpring

__all__ = ["SpoolMass", "Mass", "Fixed", "Free", "LinearSpring", "TwoFlangeSpring", "TwoStageSpring",
           "CenteringSpring", "Friction", "LuGreFriction", "Damper", "TwoFlangeDamper", "EndStop", "ForceInput",
           "PositionInput", "VelocityInput", "ForceSource", "VelocitySource", "PositionSensor", "VelocitySensor", "ForceSensor", "RackPinion", "Lever", "Gear",
           "Inertia", "ShaftSpringDamper", "RotationalDamper", "TorqueSource", "TorqueInput",
           "SpeedSource", "SpeedInput", "RotationalFixed", "RotationalFree", "SpeedSensor", "AngleSensor",
           "TorqueSensor", "MAIN_SPOOL_MASS", "LEVER_EQUIVALENT_MASS"]
