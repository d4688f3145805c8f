"""Index-1 DAE problems of the Bari IVP Test Set, with reference solutions.

Two problems, in the residual form F(t, y, y') = M y' - f(t, y) = 0 used by the test set's
DAE drivers:

* **Chemical Akzo Nobel** (``AKZO``), n = 6, t in [0, 180]: a chemical reaction of two
  species with CO2 inflow; y6 is algebraic (0 = Ks y1 y4 - y6).
* **Transistor Amplifier** (``TRANSISTOR``), n = 8, t in [0, 0.2]: an electric circuit
  with two bipolar transistors; M is singular (rank 5) and every variable's derivative
  appears, so there is no algebraic variable in the IDA sense. The consistent initial
  derivatives are those given by the test set.

The reference solutions at t_end are the published ones (Akzo: RADAU5 at tight tolerance;
Transistor: PSIDE at rtol = atol = 1e-14 on a Cray C90). ``mescd`` is the test set's
accuracy measure, the mixed error significant correct digits.

References
----------
.. [1] F. Mazzia, C. Magherini, "Test Set for Initial Value Problem Solvers", release 2.4,
   Department of Mathematics, University of Bari and INdAM, 2008, problems "Chemical Akzo
   Nobel" and "Transistor Amplifier".
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

__all__ = ["ReferenceProblem", "AKZO", "TRANSISTOR", "PROBLEMS", "mescd",
           "akzo_residual", "akzo_jacobian", "transistor_residual", "transistor_jacobian"]


@dataclass(frozen=True)
class ReferenceProblem:
    """A DAE with consistent initial values and a reference solution at ``t_span[1]``."""

    name: str
    residual: Callable
    jac: Callable
    t_span: tuple
    y0: np.ndarray
    yp0: np.ndarray
    y_ref: np.ndarray
    algebraic: Optional[list]
    var_names: list


def mescd(y, y_ref, atol, rtol):
    """Mixed error significant correct digits: -log10 max_i |y_i - ref_i| / (atol/rtol + |ref_i|)."""
    y = np.asarray(y, dtype=float)
    y_ref = np.asarray(y_ref, dtype=float)
    err = np.abs(y - y_ref) / (np.asarray(atol) / np.asarray(rtol) + np.abs(y_ref))
    worst = float(np.max(err))
    return math.inf if worst == 0.0 else -math.log10(worst)


# --------------------------------------------------------------- Chemical Akzo Nobel
AKZO_K1, AKZO_K2, AKZO_K3, AKZO_K4 = 18.7, 0.58, 0.09, 0.42
AKZO_KBIG = 34.4        # equilibrium constant K
AKZO_KLA = 3.3          # mass transfer coefficient klA
AKZO_KS = 115.83        # equilibrium constant Ks
AKZO_PCO2 = 0.9         # partial CO2 pressure
AKZO_H = 737.0          # Henry constant


def _akzo_rates(y1, y2, y3, y4, y5, y6):
    """Reaction rates r1..r5 and CO2 inflow of the Akzo Nobel problem."""
    sq = math.sqrt(y2) if y2 >= 0.0 else math.nan   # y2 < 0 is outside the model
    r1 = AKZO_K1 * y1 ** 4 * sq
    r2 = AKZO_K2 * y3 * y4
    r3 = AKZO_K2 / AKZO_KBIG * y1 * y5
    r4 = AKZO_K3 * y1 * y4 * y4
    r5 = AKZO_K4 * y6 * y6 * sq
    fin = AKZO_KLA * (AKZO_PCO2 / AKZO_H - y2)
    return r1, r2, r3, r4, r5, fin


def _akzo_f(y):
    """Right-hand side f(y) of M y' = f(y) for Akzo Nobel."""
    y1, y2, y3, y4, y5, y6 = y
    r1, r2, r3, r4, r5, fin = _akzo_rates(y1, y2, y3, y4, y5, y6)
    return [-2.0 * r1 + r2 - r3 - r4,
            -0.5 * r1 - r4 - 0.5 * r5 + fin,
            r1 - r2 + r3,
            -r2 + r3 - 2.0 * r4,
            r2 - r3 + r5,
            AKZO_KS * y1 * y4 - y6]


def akzo_residual(t, y, yp):
    """F = M y' - f(y) with M = diag(1, 1, 1, 1, 1, 0)."""
    f = _akzo_f(y.tolist())
    p = yp.tolist()
    return np.array([p[0] - f[0], p[1] - f[1], p[2] - f[2], p[3] - f[3], p[4] - f[4], -f[5]])


def akzo_jacobian(t, y, yp, c):
    """dF/dy + c dF/dy' = -df/dy + c M."""
    y1, y2, y3, y4, y5, y6 = y.tolist()
    sq = math.sqrt(y2) if y2 > 0.0 else math.nan
    r11 = 4.0 * AKZO_K1 * y1 ** 3 * sq
    r12 = 0.5 * AKZO_K1 * y1 ** 4 / sq
    r23 = AKZO_K2 * y4
    r24 = AKZO_K2 * y3
    r31 = AKZO_K2 / AKZO_KBIG * y5
    r35 = AKZO_K2 / AKZO_KBIG * y1
    r41 = AKZO_K3 * y4 * y4
    r44 = 2.0 * AKZO_K3 * y1 * y4
    r52 = 0.5 * AKZO_K4 * y6 * y6 / sq
    r56 = 2.0 * AKZO_K4 * y6 * sq
    dfdy = np.array([
        [-2.0 * r11 - r31 - r41, -2.0 * r12, r23, r24 - r44, -r35, 0.0],
        [-0.5 * r11 - r41, -0.5 * r12 - 0.5 * r52 - AKZO_KLA, 0.0, -r44, 0.0, -0.5 * r56],
        [r11 + r31, r12, -r23, -r24, r35, 0.0],
        [r31 - 2.0 * r41, 0.0, -r23, -r24 - 2.0 * r44, r35, 0.0],
        [-r31, r52, r23, r24, -r35, r56],
        [AKZO_KS * y4, 0.0, 0.0, AKZO_KS * y1, 0.0, -1.0],
    ])
    out = -dfdy
    out[np.arange(5), np.arange(5)] += c
    return out


def _akzo_initial():
    y0 = np.array([0.444, 0.00123, 0.0, 0.007, 0.0, AKZO_KS * 0.444 * 0.007])
    f = _akzo_f(y0.tolist())
    yp0 = np.array(f[:5] + [0.0])
    return y0, yp0


_AKZO_Y0, _AKZO_YP0 = _akzo_initial()

AKZO = ReferenceProblem(
    name="Chemical Akzo Nobel",
    residual=akzo_residual,
    jac=akzo_jacobian,
    t_span=(0.0, 180.0),
    y0=_AKZO_Y0,
    yp0=_AKZO_YP0,
    y_ref=np.array([0.1150794920661702, 0.1203831471567715e-2, 0.1611562887407974,
                    0.3656156421249283e-3, 0.1708010885264404e-1, 0.4873531310307455e-2]),
    algebraic=[5],
    var_names=["FLB", "CO2", "FLBT", "ZHU", "FLBC", "ZLA"],
)

# ------------------------------------------------------------- Transistor Amplifier
TR_UB = 6.0             # operating voltage [V]
TR_UF = 0.026           # thermal voltage [V]
TR_ALPHA = 0.99
TR_BETA = 1e-6
TR_R0 = 1000.0
TR_R = 9000.0           # R1 .. R9
TR_C = (1e-6, 2e-6, 3e-6, 4e-6, 5e-6)    # C1 .. C5


def _transistor_f(t, y):
    """Right-hand side f(t, y) of M y' = f(t, y) for the transistor amplifier."""
    y1, y2, y3, y4, y5, y6, y7, y8 = y
    ue = 0.1 * math.sin(200.0 * math.pi * t)
    g1 = TR_BETA * (math.exp((y2 - y3) / TR_UF) - 1.0)
    g2 = TR_BETA * (math.exp((y5 - y6) / TR_UF) - 1.0)
    return [(y1 - ue) / TR_R0,
            y2 / TR_R + (y2 - TR_UB) / TR_R + (1.0 - TR_ALPHA) * g1,
            y3 / TR_R - g1,
            (y4 - TR_UB) / TR_R + TR_ALPHA * g1,
            y5 / TR_R + (y5 - TR_UB) / TR_R + (1.0 - TR_ALPHA) * g2,
            y6 / TR_R - g2,
            (y7 - TR_UB) / TR_R + TR_ALPHA * g2,
            y8 / TR_R]


def transistor_residual(t, y, yp):
    """F = M y' - f(t, y) with the test set's mass matrix (rank 5)."""
    f = _transistor_f(t, y.tolist())
    p1, p2, p3, p4, p5, p6, p7, p8 = yp.tolist()
    c1, c2, c3, c4, c5 = TR_C
    d12 = c1 * (p2 - p1)
    d45 = c3 * (p5 - p4)
    d78 = c5 * (p8 - p7)
    return np.array([d12 - f[0], -d12 - f[1], -c2 * p3 - f[2], d45 - f[3], -d45 - f[4],
                     -c4 * p6 - f[5], d78 - f[6], -d78 - f[7]])


def transistor_jacobian(t, y, yp, c):
    """dF/dy + c dF/dy' = -df/dy + c M."""
    y = y.tolist()
    e1 = TR_BETA * math.exp((y[1] - y[2]) / TR_UF) / TR_UF
    e2 = TR_BETA * math.exp((y[4] - y[5]) / TR_UF) / TR_UF
    a = TR_ALPHA
    g = 1.0 / TR_R
    c1, c2, c3, c4, c5 = (c * ci for ci in TR_C)
    return np.array([
        [-1.0 / TR_R0 - c1, c1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [c1, -2.0 * g - (1.0 - a) * e1 - c1, (1.0 - a) * e1, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.0, e1, -g - e1 - c2, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.0, -a * e1, a * e1, -g - c3, c3, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, c3, -2.0 * g - (1.0 - a) * e2 - c3, (1.0 - a) * e2, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0, e2, -g - e2 - c4, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0, -a * e2, a * e2, -g - c5, c5],
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, c5, -g - c5],
    ])


def _transistor_initial():
    y2 = TR_UB / (TR_R / TR_R + 1.0)
    y0 = np.array([0.0, y2, y2, TR_UB, y2, y2, TR_UB, 0.0])
    yp0 = np.array([51.338775, 51.338775, -y2 / (TR_C[1] * TR_R), -24.9757667, -24.9757667,
                    -y2 / (TR_C[3] * TR_R), -10.00564453, -10.00564453])
    return y0, yp0


_TR_Y0, _TR_YP0 = _transistor_initial()

TRANSISTOR = ReferenceProblem(
    name="Transistor Amplifier",
    residual=transistor_residual,
    jac=transistor_jacobian,
    t_span=(0.0, 0.2),
    y0=_TR_Y0,
    yp0=_TR_YP0,
    y_ref=np.array([-0.5562145012262709e-2, 0.3006522471903042e1, 0.2849958788608128e1,
                    0.2926422536206241e1, 0.2704617865010554e1, 0.2761837778393145e1,
                    0.4770927631616772e1, 0.1236995868091548e1]),
    algebraic=None,
    var_names=[f"U{i}" for i in range(1, 9)],
)

PROBLEMS = {"akzo": AKZO, "transistor": TRANSISTOR}
