"""Shared physical laws and their smooth regularisations.

Every component uses these rather than writing its own, so one regularisation is documented and
tested once. All work on numbers and on symbolic expressions alike.

References
----------
.. [A1] PVG 32 modelling report (2009), appendix A.1-A.2: the orifice equation
   Q = Cd * A * sqrt(2 * dp / rho), eq. (A.4).
.. [A3] Ibid., appendix A.3: viscous and Coulomb friction.
.. [A4] Ibid., appendix A.4: flow force F = 2 * Cd * A * dp * cos(theta), eq. (A.6).
.. [A5] Ibid., appendix A.5: continuity, V / beta * dp/dt = sum Q - dV/dt.
.. [MSL] Modelica Standard Library, ``Modelica.Fluid.Utilities.regRoot``: the regularised
   square root x / (x^2 + delta^2)^(1/4).
"""

from __future__ import annotations

import math

from . import expr as E

__all__ = [
    "reg_root", "orifice_flow", "orifice_transition_pressure", "flow_force", "smooth_abs",
    "smooth_sign", "smooth_max", "smooth_min", "smooth_pos", "smooth_clip",
    "coulomb_friction", "rho_default",
]

rho_default = 870.0  # mineral hydraulic oil [kg/m^3]


def _sqrt(x):
    return E.sqrt(x) if isinstance(x, E.Expr) else math.sqrt(x)


def _tanh(x):
    return E.tanh(x) if isinstance(x, E.Expr) else math.tanh(x)


def _exp(x):
    return E.exp(x) if isinstance(x, E.Expr) else math.exp(x)


def reg_root(x, delta):
    """Regularised signed square root ``x / (x^2 + delta^2)^(1/4)`` [MSL].

    Equals ``sign(x) * sqrt(|x|)`` to within 0.3 % for ``|x| > 10 * delta`` and is linear with
    slope ``1/sqrt(delta)`` at zero: a laminar-like, infinitely differentiable transition.
    """
    return x / _sqrt(_sqrt(x * x + delta * delta))


def orifice_flow(Cd, A, dp, rho, dp_t):
    """Turbulent orifice flow with a smooth laminar transition [A1, eq. A.4].

    ``Q = Cd * A * sqrt(2/rho) * reg_root(dp, dp_t)``: ``Cd*A*sqrt(2|dp|/rho)*sign(dp)`` for
    ``|dp| >> dp_t``, linear in ``dp`` for ``|dp| << dp_t``.
    """
    return Cd * A * math.sqrt(2.0 / rho) * reg_root(dp, dp_t)


def orifice_transition_pressure(Cd, D_h, rho, nu, Re_crit):
    """Pressure drop at which an orifice of hydraulic diameter ``D_h`` reaches ``Re_crit``.

    From Re = v * D_h / nu and v = Cd * sqrt(2 dp / rho): dp_t = rho/2 * (Re * nu / (Cd*D_h))^2.
    """
    return 0.5 * rho * (Re_crit * nu / (Cd * D_h)) ** 2


def flow_force(Cd, A, dp, theta):
    """Steady flow force on a spool, ``2 * Cd * A * dp * cos(theta)`` [A4, eq. A.6]."""
    return 2.0 * Cd * A * dp * math.cos(theta)


def smooth_abs(x, eps):
    """``sqrt(x^2 + eps^2)``: |x| rounded within ``eps`` of zero."""
    return _sqrt(x * x + eps * eps)


def smooth_sign(x, eps):
    """``tanh(x / eps)``: sign(x) with a transition of width ``eps``."""
    return _tanh(x / eps)


def smooth_pos(x, eps):
    """``(x + sqrt(x^2 + eps^2)) / 2``: max(x, 0) rounded within ``eps`` of zero.

    Used for openings past a dead band: area = k * smooth_pos(x - x_dead, eps).
    """
    return 0.5 * (x + smooth_abs(x, eps))


def smooth_max(a, b, eps):
    """max(a, b) rounded within ``eps``."""
    return 0.5 * (a + b + smooth_abs(a - b, eps))


def smooth_min(a, b, eps):
    """min(a, b) rounded within ``eps``."""
    return 0.5 * (a + b - smooth_abs(a - b, eps))


def smooth_clip(x, lo, hi, eps):
    """x limited to [lo, hi], rounded within ``eps`` of each limit."""
    return smooth_min(smooth_max(x, lo, eps), hi, eps)


def coulomb_friction(v, F_c, F_s, v_s, v_eps, b):
    """Friction force opposing velocity ``v`` [A3]: viscous + Coulomb + Stribeck, smooth.

    ``F = b*v + (F_c + (F_s - F_c) * exp(-(v/v_s)^2)) * tanh(v / v_eps)``. ``v_eps`` sets the
    width of the stiction regularisation; choose it well below the velocities of interest.
    """
    return b * v + (F_c + (F_s - F_c) * _exp(-(v / v_s) * (v / v_s))) * _tanh(v / v_eps)
