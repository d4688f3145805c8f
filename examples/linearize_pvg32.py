"""Linearise the PVG 32 rig at the test-9 operating point (U_input = 4.29 V on test 9's load:
large L1 and L3, L2 closed, as ``pvgraph linearize --scenario test-9``) and check the linear
step response against the nonlinear model.

Inputs: the PVE input voltage ``U``. Outputs: the main spool position
``pvg.pvb.main_spool.flange.x`` and the load (LS) pressure ``load.f.port.p``.

Run: ``python examples/linearize_pvg32.py [out.png]`` (default examples/output/).
"""

from __future__ import annotations

import os
import sys

import numpy as np

from pvgraph.circuits.pvg32.parameters import report_tuned
from pvgraph.circuits.rig import build_rig, laminar_load
from pvgraph.circuits.scenarios import get_scenario
from pvgraph.analysis import linearize_circuit, steady_state
from pvgraph.simulate import simulate

SCENARIO = get_scenario("test-9")
U0 = SCENARIO.U_input   # [V] test-9 operating point (4.29 V)
DU = 0.01        # [V] small input step for the comparison
T_END = 0.3      # [s] duration of the step comparison
OUTPUTS = ["pvg.pvb.main_spool.flange.x", "load.f.port.p"]
X = OUTPUTS[0]

#: where the figures go unless a folder is given: examples/output/, not the repository root
OUTPUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "output")


def build(u: dict, p=None):
    """The rig on test 9's load at the input voltage ``u["U"]`` (a fresh load each time: a
    circuit instance joins one rig only)."""
    p = p or report_tuned()
    load = laminar_load(p, L1=SCENARIO.orifice_L1 or "small", L3=SCENARIO.orifice_L3,
                        l2_open=SCENARIO.l2_open_finally)
    return build_rig(p, load=load, U_input=u["U"])


def main(path: str = os.path.join(OUTPUT, "linearize_pvg32.png"), *,
         verbose: bool = True) -> dict:

    system = build({"U": U0}).compile()
    op = steady_state(system)
    lm = linearize_circuit(build, {"U": U0}, OUTPUTS, op=op)
    poles = lm.poles()
    t = np.linspace(0.0, T_END, 61)
    dx_lin = lm.step(t, X, "U", DU)
    # nonlinear: start at the operating point of U0, apply U0 + DU
    stepped = build({"U": U0 + DU}).compile()
    sol = simulate(stepped, T_END, rtol=1e-7, t_eval=t, y0=op.y)
    dx_nl = sol[X] - op[X]
    if verbose:
        print(f"operating point U = {U0} V ({SCENARIO.name}'s load): "
              f"x_main = {op[X] * 1e3:.4f} mm, "
              f"p_load = {op[OUTPUTS[1]] / 1e5:.2f} bar ({op.method}, {op.iterations} it.)")
        print(f"{len(lm.state_names)} states; dominant poles [1/s]:")
        for s in poles[:6]:
            print(f"  {s.real:12.4g} {s.imag:+12.4g}j")
        g = lm.dc_gain()
        print(f"DC gain: dx/dU = {g[0, 0] * 1e3:.4g} mm/V, dp_load/dU = {g[1, 0] / 1e5:.4g} bar/V")
        print(" t [s]   dx linear [um]   dx nonlinear [um]")
        for k in range(0, len(t), 10):
            print(f"{t[k]:6.3f}  {dx_lin[k] * 1e6:14.4f}  {dx_nl[k] * 1e6:16.4f}")
    from pvgraph.plotting import plot_step_response
    plot_step_response([(t, dx_lin * 1e6, "linear"), (t, dx_nl * 1e6, "nonlinear")], path,
                       ylabel="main spool position change [um]",
                       title=f"PVG 32: step {DU} V at U = {U0} V")
    return {"model": lm, "op": op, "poles": poles, "t": t, "dx_linear": dx_lin,
            "dx_nonlinear": dx_nl, "path": path}


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(OUTPUT, "linearize_pvg32.png"))
