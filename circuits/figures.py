"""Figures of docs/pvg32_model.md that compare model variants on the solenoid-step tests.

``python -m pvgraph.circuits.figures docs/img`` regenerates them (about a minute; without a folder they go to ``pvgraph-figures``): the pressure drop over L3
after the L2 step (report figures 4.41-4.48) for

- ``pve_delay_steps.png``: the PVE valves' switching delays (4.5.5: 20 ms NC, 3 ms NO) as one
  first-order lag each (the model) against a chain of 4 lags of a quarter of the delay (nearer
  the report's pure delay: ``pve.delay_stages``), and the 3.5 mm spool step of figure 4.62
  (``pve_delay_steps_spool.png``);
- ``lever_mass_steps.png``: the report's lever-equivalent mass 1.569 kg (eq 4.82, kept)
  against the physical 0.157 kg (I / r^2 with the report's own inertia).
"""

from __future__ import annotations

import os
import sys

from pvgraph.circuits.plotting import plot_step_comparison
from pvgraph.units import bar, mm

from .pvg32.parameters import report_tuned, with_values
from .validation import run_scenario

__all__ = ["variant_traces", "with_delay_stages", "spool_step", "step_metrics", "delay_figure",
           "lever_mass_figure"]

TESTS = ("test-2", "test-3", "test-8", "test-9")


def variant_traces(variants: dict, tests=TESTS) -> dict:
    """``{test: {label: ScenarioResult}}`` for parameter ``variants`` ``{label: params}``."""
    return {t: {label: run_scenario(t, p) for label, p in variants.items()} for t in tests}


def with_delay_stages(p, stages: int):
    """``p`` with the PVE valves' switching delays as ``stages`` lags each (pve.delay_stages)."""
    return p.model_copy(update={"pve": p.pve.model_copy(update={"delay_stages": stages})})


def spool_step(p, x_set: float = mm(3.5), t_end: float = 0.6):
    """``(t, x_m)``: the main spool after a set-point step 0 -> ``x_set`` (report figure 4.62)
    on the PVB + PVE between ideal pressures (pump 45, load 30, return 5 bar, tank 0), from the
    steady state at x_set = 0."""
    import numpy as np

    from pvgraph import Circuit
    from pvgraph.analysis import steady_state
    from pvgraph.components.hydraulic import Tank
    from pvgraph.components.signal import Constant
    from pvgraph.simulate import simulate

    from .pvg32.modules import build_pvb, build_pve

    def bench(x):
        c = Circuit("pve_bench")
        pvb, pve = c.add("pvb", build_pvb(p)), c.add("pve", build_pve(p))
        tanks = {k: c.add(k, Tank(p0=v)) for k, v in (("pump", bar(45.0)), ("load", bar(30.0)),
                                                       ("ret", bar(5.0)), ("tank", 0.0))}
        u = c.add("U", Constant(k=(x - p.pve.input_offset) / p.pve.input_gain
                                * p.rig.supply_voltage))
        c.connect(tanks["pump"].port, pvb.P)
        c.connect(tanks["load"].port, pvb.A)
        c.connect(tanks["ret"].port, pvb.B)
        c.connect(tanks["tank"].port, pvb.T, pve.T)
        c.connect(pvb.spool, pve.spool)
        c.connect(u.y, pve.U)
        return c.compile()

    t = np.linspace(0.0, t_end, 1201)
    op = steady_state(bench(0.0))
    sol = simulate(bench(x_set), t_end, rtol=1e-6, t_eval=t, y0=op.y)
    return t, np.asarray(sol["pvb.main_spool.flange.x"])


def step_metrics(t, x, x_set):
    """Overshoot [%] over the final value and 2 % settling time [s] of a step response."""
    final = x[-1]
    outside = abs(x - final) > 0.02 * abs(final)
    return {"overshoot": float(100.0 * (x.max() - final) / final),
            "settling_time": float(t[outside][-1]) if outside.any() else 0.0,
            "final_mm": float(1e3 * final)}


def delay_figure(path: str, stages: int = 4) -> str:
    """The lab step tests and the 3.5 mm spool step with the delays as one lag and as
    ``stages`` lags."""
    import matplotlib.pyplot as plt

    p = report_tuned()
    chain = with_delay_stages(p, stages)
    labels = ("delays as one lag (model)", f"delays as {stages} lags (near the pure delay)")
    out = plot_step_comparison(
        variant_traces(dict(zip(labels, (p, chain)))), path,
        title="PVE switching delays: dp over L3 after the L2 step")
    fig, ax = plt.subplots(figsize=(6, 3.2))
    for k, (label, q) in enumerate(zip(labels, (p, chain))):
        t, x = spool_step(q)
        m = step_metrics(t, x, mm(3.5))
        ax.plot(t, 1e3 * x, color=f"C{3 + k}", label=f"{label}: overshoot "
                f"{m['overshoot']:.1f} %, 2 % settling {1e3 * m['settling_time']:.0f} ms")
    ax.set_xlabel("time after the set-point step [s]")
    ax.set_ylabel("main spool x_m [mm]")
    ax.set_title("3.5 mm set-point step (figure 4.62)", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=6)
    fig.tight_layout()
    spool = path.replace(".png", "_spool.png")
    fig.savefig(spool, dpi=110)
    plt.close(fig)
    return f"{out}, {spool}"


def lever_mass_figure(path: str) -> str:
    p = report_tuned()
    light = with_values(p, {"main_spool.lever_equivalent_mass": 0.157})
    return plot_step_comparison(
        variant_traces({"lever 1.569 kg (report)": p, "lever 0.157 kg (I/r^2)": light}), path,
        title="Main-spool lever mass: dp over L3 after the L2 step")


def main(argv: list[str] | None = None) -> int:
    """Draw the documentation's extra figures into a folder; return 0 (2 for bad arguments)."""
    import argparse
    parser = argparse.ArgumentParser(
        prog="python -m pvgraph.circuits.figures",
        description="Draw the PVE delay and lever-mass step figures (about a minute); the "
                    "documentation's are regenerated with the folder docs/img.")
    parser.add_argument("folder", nargs="?", default="pvgraph-figures",
                        help="output folder (default: %(default)s)")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    if os.path.exists(args.folder) and not os.path.isdir(args.folder):
        parser.error(f"{args.folder!r} is a file; give a folder")
    os.makedirs(args.folder, exist_ok=True)
    for make, name in ((delay_figure, "pve_delay_steps.png"),
                       (lever_mass_figure, "lever_mass_steps.png")):
        print("wrote", make(os.path.join(args.folder, name)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
