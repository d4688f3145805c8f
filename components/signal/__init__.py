"""Signal components: causal sources and blocks, the LVDT sensor and the PVE controller.

Signal ports carry one value ``u``/``y`` and are causal: an output (``SignalOut``) drives any
number of inputs (``SignalIn``).
"""

from .blocks import PID, FirstOrderLag, Gain, Integrator, Product, Saturation, Sum, Sum3
from .lvdt import LVDT
from .pve_controller import PVEController
from .sources import Constant, Pulse, Ramp, Sine, Step, TimeTable

__all__ = ["Constant", "Step", "Ramp", "TimeTable", "Sine", "Pulse", "Gain", "Sum", "Sum3", "Saturation",
           "FirstOrderLag", "Product", "Integrator", "PID", "LVDT", "PVEController"]
