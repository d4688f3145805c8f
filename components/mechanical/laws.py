"""Shared mechanical laws: friction with a Stribeck curve and smooth stroke-limit contact.

These extend :mod:`pvgraph.laws` (which every component uses first) with the two laws the
mechanical components share. Both work on numbers and on symbolic expressions alike.

References
----------
.. [A3] PVG 32 modelling report (2009), appendix A.3, eq. (A.5): friction as viscous plus
   Coulomb plus Stribeck, ``F(v) = sigma*v + sign(v)*(F_co + F_so*exp(-|v|/C_s))``.
.. [AH] B. Armstrong-Helouvry, P. Dupont, C. Canudas de Wit, "A survey of models, analysis
   tools and compensation methods for the control of machines with friction", Automatica 30(7),
   1994: the Stribeck curve ``exp(-|v/v_s|^delta)`` with ``delta`` between 1 and 2.
"""

from __future__ import annotations

import math

from pvgraph import expr as E
from pvgraph.laws import coulomb_friction, smooth_abs

__all__ = ["stribeck_friction", "contact_penetration", "contact_indicator", "onset_penetration",
           "onset_indicator"]


def _exp(x):
    return E.exp(x) if isinstance(x, E.Expr) else math.exp(x)


def _tanh(x):
    return E.tanh(x) if isinstance(x, E.Expr) else math.tanh(x)


def stribeck_friction(v, F_c, F_s, v_s, v_eps, b, delta=2.0):
    """Friction force opposing velocity ``v`` [A3, AH]: viscous + Coulomb + Stribeck, smooth.

    ``F = b*v + (F_c + (F_s - F_c) * exp(-(|v|/v_s)^delta)) * tanh(v / v_eps)``.
    ``delta = 2`` is :func:`pvgraph.laws.coulomb_friction` itself; ``delta = 1`` is the
    exponential decay of report eq. (A.5) (``F_co = F_c``, ``F_so = F_s - F_c``,
    ``C_s = v_s``), with ``|v|`` rounded within ``v_eps`` so the law stays differentiable.
    """
    if delta == 2.0:
        return coulomb_friction(v, F_c, F_s, v_s, v_eps, b)
    speed = smooth_abs(v, v_eps)
    return b * v + (F_c + (F_s - F_c) * _exp(-((speed / v_s) ** delta))) * _tanh(v / v_eps)


def _where(cond, a, b):
    if isinstance(cond, E.Expr):
        return E.where(cond, a, b)
    return a if cond else b


def contact_penetration(depth, eps):
    """Penetration ``max(depth, 0)`` into a stop, rounded within ``eps`` [m] of first contact.

    Equals :func:`pvgraph.laws.smooth_pos`, ``(depth + s)/2`` with ``s = sqrt(depth^2 + eps^2)``,
    but uses the identical form ``eps^2 / (2*(s - depth))`` in free travel (``depth < 0``), where
    ``depth + s`` would cancel and leave only rounding noise (the far-field force and its
    derivative are then computed to full relative precision).
    """
    s = smooth_abs(depth, eps)
    return _where(depth > 0.0, 0.5 * (depth + s), 0.5 * eps * eps / (s - depth))


def contact_indicator(depth, eps):
    """d(penetration)/d(depth): 0 when free, 1 in contact, a smooth ramp of width ``eps``.

    ``(1 + depth/s)/2``, written ``eps^2 / (2*s*(s - depth))`` in free travel to avoid
    cancellation. Multiplies the contact damping so that it acts only while the stop is touched.
    """
    s = smooth_abs(depth, eps)
    return _where(depth > 0.0, 0.5 * (1.0 + depth / s), 0.5 * eps * eps / (s * (s - depth)))


def onset_penetration(depth, eps):
    """Penetration ``max(depth, 0)`` with a quadratic onset, exactly zero in free travel.

    ``0`` for ``depth <= 0``, ``depth^2 / (2 eps)`` up to ``eps``, then ``depth - eps/2``:
    continuously differentiable, and free of any force before contact (unlike
    :func:`contact_penetration`, whose tail reaches into free travel). A contact of stiffness
    ``k`` carrying a force ``F`` (beyond the onset) penetrates ``F/k + eps/2``.
    """
    c = onset_indicator(depth, eps)
    return _where(depth < eps, 0.5 * eps * c * c, depth - 0.5 * eps)


def onset_indicator(depth, eps):
    """d(onset_penetration)/d(depth): ``clip(depth/eps, 0, 1)``."""
    s = depth / eps
    if isinstance(s, E.Expr):
        return E.clip(s, 0.0, 1.0)
    return min(max(s, 0.0), 1.0)
