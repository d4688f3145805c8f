"""Swap the load of the PVG 32 rig: the report's laminar load, then a cylinder lifting a mass.

``build_rig(load=...)`` takes any circuit exposing hydraulic ports ``A`` and ``B``; the valve is
not touched. With 4.24 V in (below half the 11.5 V supply) the main spool feeds port B, which
is the piston side of the cylinder (``pvgraph.circuits.rig.cylinder_load``, 40/22 mm, lifting 200 kg
against a spring), so the cylinder extends.

Run: ``python examples/swap_load.py`` (writes swap_load.png).
"""

from __future__ import annotations

import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from pvgraph.circuits.pvg32.parameters import report_tuned  # noqa: E402
from pvgraph.circuits.rig import build_rig, cylinder_load, laminar_load  # noqa: E402
from pvgraph.simulate import simulate  # noqa: E402
from pvgraph.units import to_bar, to_lpm  # noqa: E402

U_INPUT = 4.24      # [V]: feeds port B
T_END = 0.8         # [s]: the cylinder travels about 0.15 m
T_STEADY = 8.0      # [s]: the laminar load at its operating point (pvgraph validate's test 1)
D_PISTON = 0.04     # [m]: the piston of circuits.rig.cylinder_load


PROBES = {"pump": "pvg.pvp.Vp.port.p", "LS": "pvg.pvb.LS_channel.port.p",
          "port_B": "pvg.pvb.PB.b.p", "port_A": "pvg.pvb.AT.a.p"}

#: where the figures go unless a folder is given: examples/output/, not the repository root
OUTPUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "output")


def _summary(sol) -> dict:
    out = {k: to_bar(sol.final(n)) for k, n in PROBES.items()}
    out["q_B_lpm"] = to_lpm(sol.final("pvg.pvb.PB.q"))
    out["x_spool_mm"] = 1000 * sol.final("pvg.pvb.main_spool.flange.x")
    out["margin"] = out["pump"] - out["LS"]
    return out


def main(outdir=OUTPUT) -> dict:
    p = report_tuned()
    results, sols = {}, {}
    for label, load in (("laminar", laminar_load(p)), ("cylinder", cylinder_load(p))):
        sols[label] = simulate(build_rig(p, load=load, U_input=U_INPUT), t_end=T_END, rtol=1e-4)
        results[label] = _summary(sols[label])
    # at 0.8 s both runs are still moving (the cylinder by design); the laminar load's
    # operating point is where it settles, as pvgraph validate runs it
    steady = simulate(build_rig(p, load=laminar_load(p), U_input=U_INPUT), t_end=T_STEADY,
                      rtol=1e-4)
    results["laminar, 8 s"] = _summary(steady)
    cyl = sols["cylinder"]
    results["cylinder"]["x_rod_start"] = float(cyl["load.cylinder.flange.x"][0])
    results["cylinder"]["x_rod_final"] = cyl.final("load.cylinder.flange.x")
    results["cylinder"]["v_rod"] = cyl.final("load.cylinder.v")
    results["cylinder"]["A_cap"] = math.pi / 4 * D_PISTON ** 2

    print(f"at t = {T_END:g} s (still moving; the laminar load settles by 8 s):")
    print(f"{'':13s} {'pump':>7s} {'LS':>7s} {'port B':>7s} {'port A':>7s} {'margin':>7s} "
          f"{'Q_B':>7s}")
    for label, r in results.items():
        print(f"{label:13s} {r['pump']:7.2f} {r['LS']:7.2f} {r['port_B']:7.2f} "
              f"{r['port_A']:7.2f} {r['margin']:7.2f} {r['q_B_lpm']:7.2f}   [bar, L/min]")
    print(f"cylinder rod: {1000 * results['cylinder']['x_rod_final']:.1f} mm at "
          f"{results['cylinder']['v_rod']:.3f} m/s")

    fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for label, sol in sols.items():
        axes[0].plot(sol.t, to_bar(sol[PROBES["LS"]]), label=f"{label}: LS")
        axes[0].plot(sol.t, to_bar(sol[PROBES["pump"]]), "--", label=f"{label}: pump")
        axes[1].plot(sol.t, to_lpm(sol["pvg.pvb.PB.q"]), label=label)
    axes[0].set_ylabel("[bar]")
    axes[1].set_ylabel("Q_B [L/min]")
    axes[1].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    os.makedirs(outdir, exist_ok=True)
    fig.savefig(os.path.join(outdir, "swap_load.png"), dpi=100)
    plt.close(fig)
    return results


if __name__ == "__main__":
    main()
