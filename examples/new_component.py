"""Write a new component and unit-test it with ``pvgraph.testing.bench_circuit``.

A spring-loaded piston accumulator: oil volume ``V`` behind a piston of area ``A`` held by a
spring of rate ``k`` with preload ``F0``. Its pressure rises linearly with the stored volume::

    der(V) = port.q                         (incompressible oil, q positive into the component)
    port.p = (F0 + k * V / A) / A

The tests: the residual vanishes at an analytic point, and with a constant flow ``Q`` in the
pressure is ``(F0 + k * (V0 + Q t) / A) / A`` at every time.

Run: ``python examples/new_component.py``.
"""

from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import numpy as np  # noqa: E402
from pydantic import Field  # noqa: E402

from pvgraph import Component, Hydraulic, Params  # noqa: E402
from pvgraph.component import Variable, der  # noqa: E402
from pvgraph.simulate import simulate  # noqa: E402
from pvgraph.testing import Flow, bench_circuit  # noqa: E402
from pvgraph.units import litre, lpm, to_bar  # noqa: E402


# --- the component (about 30 lines) -------------------------------------------------------------
class SpringAccumulatorParams(Params):
    A: float = Field(..., gt=0, le=1, description="Piston area [m^2]")
    k: float = Field(..., gt=0, le=1e9, description="Spring rate [N/m]")
    F0: float = Field(0.0, ge=0, le=1e7, description="Spring preload at V = 0 [N]")
    V0: float = Field(0.0, ge=0, le=10, description="Initial oil volume [m^3]")


class SpringAccumulator(Component):
    """Spring-loaded piston accumulator: ``port.p = (F0 + k V / A) / A``, ``der(V) = port.q``."""

    Params = SpringAccumulatorParams
    ports = {"port": Hydraulic("oil connection")}
    variables = {"V": Variable("m^3", lambda p: p.V0, 1e-4, "stored oil volume")}

    def equations(self, v, p):
        p_spring = (p.F0 + p.k * v.V / p.A) / p.A
        v.observe("x", v.V / p.A, "m", "piston travel")
        return [der(v.V) - v.port.q,
                v.port.p - p_spring]


# --- the tests -----------------------------------------------------------------------------------
A, K, F0 = 20e-4, 5e4, 2000.0          # preload pressure 10 bar, 125 bar per litre
Q = lpm(6)

#: where the figures go unless a folder is given: examples/output/, not the repository root
OUTPUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "output")


def analytic_pressure(V):
    return (F0 + K * V / A) / A


def _vector(system, values):
    y = np.array(system.y0, dtype=float)
    for name, value in values.items():
        coef, idx, off = system.resolve(name)
        y[idx] = (value - off) / coef
    return y


def residual_at_analytic_point() -> float:
    """Largest |residual| (relative) at V = 0.2 L, p analytic, der(V) = Q."""
    system = bench_circuit(SpringAccumulator(A=A, k=K, F0=F0), port=Flow(Q)).compile()
    V = litre(0.2)
    y = _vector(system, {"dut.V": V, "dut.port.p": analytic_pressure(V)})
    yp = np.zeros(system.n)
    yp[system.index["dut.V"]] = Q
    res = system.residual(0.0, y, yp)
    scale = np.array([Q if "V" in n else analytic_pressure(V) for n in system.names])
    return float(np.max(np.abs(res) / scale))


def transient_vs_analytic(t_end=2.0) -> dict:
    sol = simulate(bench_circuit(SpringAccumulator(A=A, k=K, F0=F0), port=Flow(Q)),
                   t_end=t_end, rtol=1e-8)
    p_exact = analytic_pressure(Q * sol.t)
    err = np.max(np.abs(sol["dut.port.p"] - p_exact)) / np.max(p_exact)
    return {"p_final_bar": to_bar(sol.final("dut.port.p")),
            "p_final_analytic_bar": to_bar(analytic_pressure(Q * t_end)),
            "max_rel_error": float(err),
            "x_final": sol.final("dut.x")}


def main(outdir=OUTPUT) -> dict:
    result = {"residual": residual_at_analytic_point(), **transient_vs_analytic()}
    print(f"residual at the analytic point (relative): {result['residual']:.2e}")
    print(f"pressure after 2 s of {Q * 60000:.0f} L/min: {result['p_final_bar']:.3f} bar "
          f"(analytic {result['p_final_analytic_bar']:.3f} bar), largest relative error "
          f"{result['max_rel_error']:.2e}")
    return result


if __name__ == "__main__":
    main()
