"""A lift-swing-lower cycle of the load-sensing machine circuit (``circuits/machine.py``).

A load-sensing pump feeds two PVG 32 sections: the boom section lifts 1500 kg on a cylinder
with a counterbalance valve until the cylinder's end stop, then holds; the swing section turns
a 40 kg m^2 inertia through a hydraulic motor and stops it against its cross-port relief
valves; then the boom lowers, metered by the counterbalance valve. Prints the LS margin, the
pressures that the cut-off and the relief valves hold, and the energy delivered where.

Run: ``python examples/machine_cycle.py [outdir]`` (writes machine_cycle.png to outdir, default
examples/output/).
"""

from __future__ import annotations

import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from pvgraph.circuits.machine import CYCLE, RTOL, SPEC, build_machine  # noqa: E402
from pvgraph.plotting import plot_solution  # noqa: E402
from pvgraph.simulate import simulate  # noqa: E402
from pvgraph.units import to_bar  # noqa: E402

T_END = CYCLE["t"][-1]


def _window(sol, name, t0, t1):
    mask = (sol.t >= t0) & (sol.t <= t1)
    return sol[name][mask]


def _integral(sol, values):
    return float(np.trapezoid(values, sol.t))


def run(rtol: float = RTOL):
    """Simulate the cycle; the Solution at 200 points per second (``RTOL``: see machine.py)."""
    return simulate(build_machine(), T_END, rtol=rtol,
                    t_eval=np.linspace(0.0, T_END, int(T_END * 200) + 1))


def summarise(sol) -> dict:
    """The numbers the example prints and the tests check."""
    margin = _window(sol, "pump.b.p", 1.0, 1.8) - _window(sol, "ls_line.port.p", 1.0, 1.8)
    x = sol["boom_cylinder.flange.x"]
    F_cyl = sol["boom_cylinder.F"]
    v = sol["boom_mass.v"]
    swing_lines = np.maximum(sol["swing_hose_A.b.p"], sol["swing_hose_B.b.p"])
    r = {
        "margin_min_bar": to_bar(margin.min()), "margin_max_bar": to_bar(margin.max()),
        "x_start": float(x[0]), "x_max": float(x.max()), "x_end": float(x[-1]),
        "x_top": float(np.median(_window(sol, "boom_cylinder.flange.x", 3.5, 4.5))),
        "F_stop_hold": float(np.median(_window(sol, "boom_cylinder.F_stop", 3.5, 4.5))),
        "p_stall_bar": to_bar(np.median(_window(sol, "pump.b.p", 2.9, 3.0))),
        "q_relief_max": float(sol["relief.q"].max()),
        "p_pump_max_bar": to_bar(sol["pump.b.p"].max()),
        "p_swing_peak_bar": to_bar(swing_lines[sol.t > 4.6].max()),
        "q_shock_max": float(max(sol["shock_AB.q"].max(), sol["shock_BA.q"].max())),
        "w_swing_max": float(sol["swing_motor.w"].max()),
        "w_swing_end": float(sol["swing_motor.w"][-1]),
        "v_lower": float(np.median(_window(sol, "boom_mass.v", 5.5, 7.0))),
        "E_cyl": _integral(sol, F_cyl * v),
        "E_stop": _integral(sol, sol["boom_cylinder.F_stop"] * v),
        "E_pot": float(SPEC.boom_mass * 9.81 * (x[-1] - x[0])),
        "E_kin_end": float(0.5 * SPEC.boom_mass * v[-1] ** 2),
        "E_motor": _integral(sol, sol["swing_motor.P_shaft"]),
        "E_swing_kin_end": float(sol["swing_inertia.E_kin"][-1]),
        "E_bearing": _integral(sol, 2.0 * sol["swing_motor.w"] ** 2),
        "E_shaft": _integral(sol, sol["pump.P_shaft"]),
        "E_hyd": _integral(sol, sol["pump.P_hyd"]),
        "E_acc_end": float(sol["accumulator.E_gas"][-1] - sol["accumulator.E_gas"][0]),
    }
    return r


#: where the figure goes unless a folder is given: examples/output/, not the repository root
OUTPUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "output")


def main(outdir=OUTPUT) -> dict:
    sol = run()
    r = summarise(sol)
    print(f"LS margin while lifting: {r['margin_min_bar']:.1f}-{r['margin_max_bar']:.1f} bar "
          f"(set {to_bar(SPEC.dp_ls):.0f})")
    print(f"boom: x {r['x_start']:.3f} -> {r['x_top']:.4f} m (stroke {SPEC.stroke} m), "
          f"stop force {r['F_stop_hold'] / 1e3:.1f} kN, pump stalls at {r['p_stall_bar']:.0f} bar "
          f"(cut-off {to_bar(SPEC.p_cutoff):.0f}); lowers at {r['v_lower']:.3f} m/s")
    print(f"swing: up to {r['w_swing_max']:.2f} rad/s, stopped at {r['p_swing_peak_bar']:.0f} bar "
          f"(shock valves {to_bar(SPEC.p_shock):.0f} bar)")
    print(f"energy: shaft {r['E_shaft'] / 1e3:.1f} kJ, pump delivered {r['E_hyd'] / 1e3:.1f} kJ, "
          f"cylinder work {r['E_cyl'] / 1e3:.2f} kJ, motor work {r['E_motor'] / 1e3:.2f} kJ")
    plot_solution(sol, ["pump.b.p", "ls_line.port.p", "boom_cylinder.A.p",
                        "boom_cylinder.flange.x", "swing_motor.w", "swing_hose_B.b.p"],
                  os.path.join(outdir, "machine_cycle.png"), title="lift, swing, lower")
    return r


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else OUTPUT)
