"""The pvgraph component library: hydraulic, mechanical and signal components."""

from .hydraulic import *  # noqa: F401,F403
from .hydraulic import __all__ as _hydraulic

__all__ = list(_hydraulic)
