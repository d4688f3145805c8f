"""Where the pump's power goes in a load-sensing PVG 32: the PVP bypass loss against load pressure.

Report 2.3: the pump delivers a constant flow; the PVP spool returns what the load does not take
to tank, at only the load-sense margin (about 15 bar, here 13 bar) above the highest load
pressure instead of at the relief setting, which is the point of load sensing. This example puts
the valve between the rig's pump and an ideal load pressure p_L on port B (what a cylinder
holding a weight presents), sets the spool to pass about 10 of the 16.3 L/min, and solves the
steady state for p_L from 10 to 160 bar. For each it splits the pump's hydraulic power with
:func:`pvgraph.analysis.hydraulic_power` into

- the PVP bypass loss (spool edge A3 to tank),
- the metering loss (compensator and main spool, P -> B),
- the power delivered to the load, p_L Q_L,
- the rest (return line, LS and pilot flows),

checks that they add up to the pump's power, and compares with a constant-pressure supply that
must always run at the highest pressure it serves (160 bar + the margin) and relieves the same
excess flow there.

Run: ``python examples/pvp_bypass_loss.py [outdir]`` (writes pvp_bypass_loss.png to outdir, default examples/output/).
"""

from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from pvgraph.circuits.pvg32.parameters import report_tuned  # noqa: E402
from pvgraph.circuits.rig import build_rig  # noqa: E402
from pvgraph.components import PressureSource, Tank  # noqa: E402
from pvgraph import Circuit  # noqa: E402
from pvgraph.analysis import hydraulic_power, steady_state  # noqa: E402
from pvgraph.units import bar, to_bar, to_lpm  # noqa: E402

U_INPUT = 4.45                                   # [V]: about 10 L/min to port B (sweep-5)
LOAD_PRESSURES = np.arange(10.0, 161.0, 10.0)    # [bar]
BYPASS = "pvg.pvp.A3"                            # PVP spool edge to tank
METERING = ("pvg.pvb.P0", "pvg.pvb.A1", "pvg.pvb.A2", "pvg.pvb.PK", "pvg.pvb.PB")

#: where the figures go unless a folder is given: examples/output/, not the repository root
OUTPUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "output")


def pressure_load(p_load: float) -> Circuit:
    """A load that holds port B at ``p_load`` and returns port A to tank."""
    c = Circuit("load")
    held = c.add("held", PressureSource(p0=p_load))
    ret = c.add("ret", Tank())
    c.expose("B", held.port, "work port at the load pressure")
    c.expose("A", ret.port, "return")
    return c


def components_with_ports(system) -> list[str]:
    names = set(system.all_names())
    return sorted({n.rsplit(".", 2)[0] for n in names
                   if n.endswith(".q") and n[:-2] + ".p" in names})


def operating_point(p_load: float, y0=None):
    system = build_rig(report_tuned(), load=pressure_load(bar(p_load)), U_input=U_INPUT).compile()
    start = y0 if y0 is not None and len(y0) == system.n else None
    return steady_state(system, y0=start, tol=1e-11)


def power_split(op) -> dict:
    """Powers [W] at an operating point; every component's absorbed power is accounted for."""
    every = {c: hydraulic_power(op, c) for c in components_with_ports(op.system)}
    pump = -every.pop("pump")
    load = every.pop("load.held")          # absorbed: p_L Q_L
    bypass = every.pop(BYPASS)
    metering = sum(every.pop(c) for c in METERING)
    every.pop("tank", None)
    every.pop("load.ret", None)
    other = sum(every.values())
    return {"pump": pump, "load": load, "bypass": bypass, "metering": metering, "other": other,
            "imbalance": pump - load - bypass - metering - other}


def main(outdir: str = OUTPUT, *, verbose: bool = True) -> dict:
    rows, y = [], None
    for pl in LOAD_PRESSURES:
        op = operating_point(pl, y)
        y = op.y
        pw = power_split(op)
        p_pump, p_ls = op["pvg.pvp.Vp.port.p"], op["pvg.pvb.V2.port.p"]
        q_bypass = op["pvg.pvp.A3.q"]
        rows.append({"p_load": pl, "p_pump": to_bar(p_pump), "margin": to_bar(p_pump - p_ls),
                     "q_load": to_lpm(op["load.held.port.q"]), "q_bypass": to_lpm(q_bypass),
                     "q_pump": to_lpm(op["pump.b.q"] * -1.0), **pw})
    p_fixed = bar(LOAD_PRESSURES[-1]) + bar(np.mean([r["margin"] for r in rows]))
    for r in rows:
        r["bypass_fixed"] = r["q_bypass"] / 60000.0 * p_fixed
    if verbose:
        print(f"PVG 32, U = {U_INPUT} V, pump {rows[0]['q_pump']:.2f} L/min; powers in W")
        print(f"{'p_L bar':>7s} {'p_P bar':>7s} {'margin':>6s} {'Q_L':>5s} {'Q_byp':>5s} "
              f"{'pump':>6s} {'load':>6s} {'bypass':>6s} {'meter':>6s} {'other':>5s} "
              f"{'byp@fix':>7s} {'eff %':>5s}")
        for r in rows:
            print(f"{r['p_load']:7.0f} {r['p_pump']:7.1f} {r['margin']:6.1f} {r['q_load']:5.2f} "
                  f"{r['q_bypass']:5.2f} {r['pump']:6.0f} {r['load']:6.0f} {r['bypass']:6.0f} "
                  f"{r['metering']:6.0f} {r['other']:5.0f} {r['bypass_fixed']:7.0f} "
                  f"{100 * r['load'] / r['pump']:5.1f}")
        print(f"constant-pressure comparison: excess flow relieved at {to_bar(p_fixed):.0f} bar")
    pl = np.array([r["p_load"] for r in rows])
    fig, ax = plt.subplots(figsize=(7, 4.2))
    ax.stackplot(pl, [r["load"] / 1e3 for r in rows], [r["metering"] / 1e3 for r in rows],
                 [r["bypass"] / 1e3 for r in rows], [r["other"] / 1e3 for r in rows],
                 labels=["to the load  p_L Q_L", "metering (compensator + main spool)",
                         "PVP bypass to tank", "return line, LS and pilot"], alpha=0.8)
    ax.plot(pl, [r["pump"] / 1e3 for r in rows], "k-", lw=1.5, label="pump  p_P Q_P")
    ax.plot(pl, [r["q_pump"] / 60000.0 * p_fixed / 1e3 for r in rows], "r--", lw=1.5,
            label=f"pump at a fixed {to_bar(p_fixed):.0f} bar (no load sensing)")
    ax.set_xlabel("load pressure p_L [bar]")
    ax.set_ylabel("power [kW]")
    ax.set_title(f"PVG 32 load sensing: where {rows[0]['q_pump']:.1f} L/min of pump power goes")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    os.makedirs(outdir, exist_ok=True)
    path = os.path.join(outdir, "pvp_bypass_loss.png")
    fig.savefig(path, dpi=120)
    plt.close(fig)
    slope, intercept = np.polyfit(pl, [r["bypass"] for r in rows], 1)
    return {"rows": rows, "path": path, "p_fixed_bar": to_bar(p_fixed),
            "bypass_slope_W_per_bar": slope, "bypass_intercept_W": intercept}


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else OUTPUT)
