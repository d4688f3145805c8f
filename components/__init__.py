"""The pvgraph component library: hydraulic, mechanical and signal components."""

from .hydraulic import *  # noqa: F401,F403
from .hydraulic import __all__ as _hydraulic
from .mechanical import *  # noqa: F401,F403
from .mechanical import __all__ as _mechanical
from .signal import *  # noqa: F401,F403
from .signal import __all__ as _signal

__all__ = list(_hydraulic) + list(_mechanical) + list(_signal)
