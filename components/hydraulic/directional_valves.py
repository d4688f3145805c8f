"""Directional spool valves: 4/3, 4/2, 3/2 and 2/2, and a servo/proportional valve.

The spool position is a signal ``u`` [-], the fraction of the stroke: for the 4/3 valve ``u = +1``
connects P -> A and B -> T, ``u = -1`` P -> B and A -> T, ``u = 0`` is the centre. Drive it from
any signal source, or from a mechanical position through a
:class:`pvgraph.components.mechanical.PositionSensor` with the gain ``1 / x_max``.

Each metering edge is a turbulent orifice (report eq. A.4) whose area follows its opening
coordinate ``s`` (``s = u`` for P-A and B-T, ``s = -u`` for P-B and A-T). An edge with lap
``lap`` (positive: overlap, closed at centre; negative: underlap, open at centre) opens, for
``edge="linear"``, as::

    A(s) = A_max * (onset(s - lap + eps/2) - onset(s - 1)) / (1 - lap) + A_leak

``onset`` is the quadratic-onset max(., 0) of width ``eps = 1e-3``
(:func:`pvgraph.components.mechanical.laws.onset_penetration`), so ``A = A_max (s - lap) / (1 - lap)``
exactly in the metering range ``lap + eps/2 <= s <= 1``: at full stroke, ``s = 1``, the area is
exactly ``A_max`` (a servo valve at full command passes its rated flow), and the rounding of the
upper corner lies past the stroke (``A`` levels off at ``A_max (1 + eps / (2 (1 - lap)))`` from
``s = 1 + eps``). With
``edge="table"`` the area is ``A_max * table(s - lap)``, linear interpolation through
``(s_table, A_table)`` (fractions of ``A_max``, held at the ends).

Centre types of the 4/3 valve (the lap of each edge):

- ``closed``: all four edges overlapped by ``lap``; all ports blocked at centre.
- ``open``: all four underlapped by ``underlap``; P, A, B, T connected at centre.
- ``tandem``: edges overlapped, plus a P -> T bypass of area ``A_max * (1 - |u| / underlap)``
  (``|u|`` rounded within ``eps * underlap``, the max with 0 within ``eps``) open at centre: the
  pump unloads to tank, A and B are blocked.
- ``float``: P edges overlapped, A-T and B-T underlapped: A and B to tank, P blocked.

Port flows (positive into the valve)::

    P.q = q_PA + q_PB + q_PT,   A.q = q_AT - q_PA,   B.q = q_BT - q_PB,   T.q = -(q_AT + q_BT + q_PT)

Flow force: the steady jet forces ``2 Cd A |dp| cos(theta)`` of the open edges (report eq. A.6)
all tend to close the valve; their sum along ``-sign(u)`` is observed as ``F_flow`` [N] for
sizing the actuator (the signal-driven spool itself is ideal).

``DirectionalValve42`` is the 4/3 geometry traversed from ``u = 0`` (P -> B, A -> T) to
``u = 1`` (P -> A, B -> T) with a closed crossover of width ``lap``: ``s = 2u - 1``, so both
positions are fully open, at exactly ``A_max``. ``DirectionalValve32``:
ports P, A, T; ``u = 1`` P -> A, ``u = 0`` A -> T. ``DirectionalValve22``: ports P, A; open at
``u = 1`` (normally closed) or at ``u = 0`` (``normally_open``).

``ServoValve``: a critically lapped 4/3 closed-centre valve whose spool follows the command
``i`` [-] (clipped to +-1) with first-order (``tau``) or second-order (``wn``, ``zeta``)
dynamics, sized by its rated flow ``Q_nom`` at the valve drop ``dp_nom`` (two edges in series,
``dp_nom / 2`` each)::

    order 1:  tau der(x) = clip(i) - x,   v = der(x)
    order 2:  der(x) = v,   der(v) = wn^2 (clip(i) - x) - 2 zeta wn v
    A_max = Q_nom / (Cd sqrt(dp_nom / rho))
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, model_validator

from pvgraph import expr as E
from pvgraph.component import (Component, Hydraulic, Params, SignalIn, Variable, check_table,
                               der)
from pvgraph.laws import orifice_flow, smooth_abs, smooth_pos

from ..mechanical.laws import onset_penetration
from .fluid import rho_field

__all__ = ["DirectionalValve43", "DirectionalValve42", "DirectionalValve32",
           "DirectionalValve22", "ServoValve", "edge_area"]

EDGE_EPS = 1e-3  # rounding of the edge opening [-] (fraction of the stroke)


class EdgeFlowParams(Params):
    """The flow law of a metering edge, shared by the spool valves."""

    A_leak: float = Field(1e-11, gt=0.0, le=1e-5,
                          description="Leakage area of each closed edge [m^2]")
    Cd: float = Field(0.6, gt=0.0, le=1.0, description="Discharge coefficient [-]")
    theta: float = Field(math.radians(69.0), ge=0.0, le=math.pi / 2,
                         description="Jet angle of the flow force [rad]")
    rho: float = rho_field()
    dp_t: float = Field(1e4, gt=0.0, le=1e6,
                        description="Laminar-turbulent transition pressure drop [Pa]")


class SpoolEdgeParams(EdgeFlowParams):
    A_max: float = Field(..., gt=0.0, le=1e-2, description="Fully open area of one edge [m^2]")
    lap: float = Field(0.05, ge=0.0, lt=0.9,
                       description="Overlap of the closed edges, fraction of the stroke [-]")
    edge: Literal["linear", "table"] = Field("linear", description="Opening law of the edges [-]")
    s_table: tuple[float, ...] | None = Field(
        None, description="Opening past the lap, fraction of the stroke [-] (edge='table'; in "
                          "[0, 1], reaching 1 - lap at full stroke)")
    A_table: tuple[float, ...] | None = Field(
        None, description="Areas at s_table, fractions of A_max [-] (edge='table')")

    @model_validator(mode="after")
    def _table(self):
        if self.edge == "table":
            if self.s_table is None or self.A_table is None:
                raise ValueError("edge='table' needs s_table and A_table")
            check_table(self.s_table, self.A_table, "s_table", "A_table (fractions of A_max)",
                        y_range=(0.0, 1.0), x_range=(0.0, 1.0))
        elif self.s_table is not None or self.A_table is not None:
            raise ValueError(f"s_table and A_table are used with edge='table' only (edge is "
                             f"{self.edge!r}): give edge='table' as well, or leave them out")
        return self


def edge_area(s, lap, p: SpoolEdgeParams):
    """Area of one metering edge at opening coordinate ``s`` with lap ``lap`` [m^2]."""
    if p.edge == "table":
        table = E.Table(p.s_table, p.A_table, method="linear", name="edge area")
        return p.A_leak + p.A_max * E.interp(table, s - lap)
    h = 0.5 * EDGE_EPS
    opening = onset_penetration(s - lap + h, EDGE_EPS) - onset_penetration(s - 1.0, EDGE_EPS)
    return p.A_leak + p.A_max * opening / (1.0 - lap)


def _edge(v, name, A, dp, p):
    q = orifice_flow(p.Cd, A, dp, p.rho, p.dp_t)
    v.observe(f"q_{name}", q, "m^3/s", f"flow through edge {name}")
    return q


def _jet(A, dp, p):
    return 2.0 * p.Cd * A * smooth_abs(dp, p.dp_t) * math.cos(p.theta)


def four_way(v, u, laps, p, A_PT=None):
    """Residuals of a four-way spool at position ``u``; ``laps`` for edges PA, BT, PB, AT."""
    P, A, B, T = v.P.p, v.A.p, v.B.p, v.T.p
    a_pa, a_bt = edge_area(u, laps[0], p), edge_area(u, laps[1], p)
    a_pb, a_at = edge_area(-u, laps[2], p), edge_area(-u, laps[3], p)
    q_pa, q_bt = _edge(v, "PA", a_pa, P - A, p), _edge(v, "BT", a_bt, B - T, p)
    q_pb, q_at = _edge(v, "PB", a_pb, P - B, p), _edge(v, "AT", a_at, A - T, p)
    q_pt = _edge(v, "PT", A_PT, P - T, p) if A_PT is not None else E.const(0.0)
    jets = (_jet(a_pa, P - A, p) + _jet(a_bt, B - T, p) - _jet(a_pb, P - B, p)
            - _jet(a_at, A - T, p))
    v.observe("F_flow", -jets, "N", "steady flow force on the spool in +u (closing)")
    v.observe("P_loss", q_pa * (P - A) + q_bt * (B - T) + q_pb * (P - B) + q_at * (A - T)
              + q_pt * (P - T), "W", "hydraulic power dissipated")
    return [v.P.q - (q_pa + q_pb + q_pt), v.A.q - (q_at - q_pa), v.B.q - (q_bt - q_pb),
            v.P.q + v.A.q + v.B.q + v.T.q]


FOUR_PORTS = {"P": Hydraulic("pressure (supply)"), "A": Hydraulic("service port A"),
              "B": Hydraulic("service port B"), "T": Hydraulic("tank (return)")}


class DirectionalValve43Params(SpoolEdgeParams):
    centre: Literal["closed", "open", "tandem", "float"] = Field(
        "closed", description="Centre type [-]: closed, open (all connected), tandem (P to T), "
                              "float (A and B to T)")
    underlap: float = Field(0.05, gt=0.0, lt=0.9,
                            description="Underlap of the edges open at centre (open, float) "
                                        "and closing width of the tandem bypass, fraction of "
                                        "the stroke [-]")


class DirectionalValve43(Component):
    """4/3 directional spool valve, driven by the spool position signal ``u`` in [-1, 1].

    ``u > 0`` opens P -> A and B -> T, ``u < 0`` P -> B and A -> T; ``u = 0`` is the centre
    (``centre``: closed, open, tandem or float)."""

    Params = DirectionalValve43Params
    ports = {**FOUR_PORTS, "u": SignalIn("spool position, fraction of the stroke", "", 1.0)}

    def equations(self, v, p):
        lap, ul = p.lap, -p.underlap
        laps = {"closed": (lap,) * 4, "open": (ul,) * 4, "tandem": (lap,) * 4,
                "float": (lap, ul, lap, ul)}[p.centre]
        A_PT = None
        if p.centre == "tandem":
            opening = 1.0 - smooth_abs(v.u, EDGE_EPS * p.underlap) / p.underlap
            A_PT = p.A_leak + p.A_max * smooth_pos(opening, EDGE_EPS)
        return four_way(v, v.u, laps, p, A_PT)


class DirectionalValve42(Component):
    """4/2 directional valve: ``u = 0`` P -> B and A -> T, ``u = 1`` P -> A and B -> T."""

    Params = SpoolEdgeParams
    ports = {**FOUR_PORTS, "u": SignalIn("spool position: 0 or 1 (fraction of the stroke)")}

    def equations(self, v, p):
        return four_way(v, 2.0 * v.u - 1.0, (p.lap,) * 4, p)


class DirectionalValve32(Component):
    """3/2 directional valve: ``u = 1`` P -> A (T blocked), ``u = 0`` A -> T (P blocked)."""

    Params = SpoolEdgeParams
    ports = {"P": FOUR_PORTS["P"], "A": FOUR_PORTS["A"], "T": FOUR_PORTS["T"],
             "u": SignalIn("spool position: 0 or 1 (fraction of the stroke)")}

    def equations(self, v, p):
        s = 2.0 * v.u - 1.0
        q_pa = _edge(v, "PA", edge_area(s, p.lap, p), v.P.p - v.A.p, p)
        q_at = _edge(v, "AT", edge_area(-s, p.lap, p), v.A.p - v.T.p, p)
        return [v.P.q - q_pa, v.T.q + q_at, v.P.q + v.A.q + v.T.q]


class DirectionalValve22Params(SpoolEdgeParams):
    normally_open: bool = Field(False, description="Open at u = 0 instead of u = 1 [-]")


class DirectionalValve22(Component):
    """2/2 directional (shut-off) valve P -> A, opened by ``u`` (or closed, if normally open)."""

    Params = DirectionalValve22Params
    ports = {"P": FOUR_PORTS["P"], "A": FOUR_PORTS["A"],
             "u": SignalIn("spool position: 0 or 1 (fraction of the stroke)")}

    def equations(self, v, p):
        s = 1.0 - 2.0 * v.u if p.normally_open else 2.0 * v.u - 1.0
        q = _edge(v, "PA", edge_area(s, p.lap, p), v.P.p - v.A.p, p)
        return [v.P.q - q, v.P.q + v.A.q]


class ServoValveParams(EdgeFlowParams):
    Q_nom: float = Field(..., gt=0.0, le=1.0,
                         description="Rated flow at full command and valve drop dp_nom [m^3/s]")
    dp_nom: float = Field(70e5, gt=0.0, le=1e8,
                          description="Rated valve pressure drop (two edges) [Pa]")
    order: Literal[1, 2] = Field(2, description="Order of the spool dynamics [-]")
    tau: float = Field(5e-3, gt=0.0, le=10.0, description="Time constant (order 1) [s]")
    wn: float = Field(2 * math.pi * 80.0, gt=0.0, le=1e5,
                      description="Natural angular frequency (order 2) [rad/s]")
    zeta: float = Field(0.7, gt=0.0, le=10.0, description="Damping ratio (order 2) [-]")

    def edges(self) -> SpoolEdgeParams:
        """The equivalent critically lapped, linear edges."""
        A_max = self.Q_nom / (self.Cd * math.sqrt(self.dp_nom / self.rho))
        return SpoolEdgeParams(A_max=A_max, lap=0.0, A_leak=self.A_leak, Cd=self.Cd,
                               theta=self.theta, rho=self.rho, dp_t=self.dp_t)


class ServoValve(Component):
    """Servo/proportional 4/3 valve (critical lap) with first- or second-order spool dynamics."""

    Params = ServoValveParams
    ports = {**FOUR_PORTS, "i": SignalIn("command, fraction of full spool stroke", "", 1.0)}
    variables = {"x": Variable("", 0.0, 1.0, "spool position, fraction of the stroke"),
                 "v": Variable("1/s", 0.0, 10.0, "spool velocity")}

    def equations(self, v, p):
        cmd = E.clip(v.i, -1.0, 1.0)
        if p.order == 1:
            dyn = [p.tau * der(v.x) - (cmd - v.x), v.v - der(v.x)]
        else:
            dyn = [der(v.x) - v.v, der(v.v) - (p.wn ** 2 * (cmd - v.x) - 2 * p.zeta * p.wn * v.v)]
        return dyn + four_way(v, v.x, (0.0,) * 4, p.edges())
