"""Plots with matplotlib: time series by name, the PVG 32 validation figures, circuit drawings.

All functions write a PNG and return its path; they use the non-interactive Agg backend so they
work on machines without a screen.
"""

from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .units import to_bar, to_lpm, to_mm  # noqa: E402

__all__ = ["plot_solution", "plot_flow_vs_voltage", "plot_cross_validation",
           "plot_step_traces", "plot_step_comparison", "draw_circuit",
           "plot_bode", "plot_step_response", "plot_opening_areas"]

_SCALES = {"Pa": (to_bar, "bar"), "m^3/s": (to_lpm, "L/min"), "m": (to_mm, "mm")}


def _save(fig, path):
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_solution(sol, names, path, *, title=None):
    """One panel per unit: the named variables over time, in engineering units."""
    groups: dict[str, list[str]] = {}
    for n in names:
        groups.setdefault(sol.unit(n), []).append(n)
    fig, axes = plt.subplots(len(groups), 1, figsize=(8, 2.6 * len(groups)), sharex=True,
                             squeeze=False)
    for ax, (unit, members) in zip(axes[:, 0], groups.items()):
        conv, label = _SCALES.get(unit, (lambda v: v, unit))
        for n in members:
            ax.plot(sol.t, conv(sol[n]), label=n)
        ax.set_ylabel(f"[{label}]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    axes[-1, 0].set_xlabel("time [s]")
    if title:
        axes[0, 0].set_title(title)
    return _save(fig, path)


_ROLE_STYLE = {"fit": ("C1", "fitted"), "held-out": ("C3", "held-out"),
               "trivial": ("0.5", "trivial")}


def plot_flow_vs_voltage(results, path, *, roles=None):
    """Steady total flow against the input voltage, measured and simulated (report fig. 4.39).

    ``roles`` maps ``(scenario, quantity)`` to "fit" / "held-out" / "trivial": the simulated
    points are coloured by the role of their flow.
    """
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for kind, marker, label in (("voltage_sweep", "o", "voltage sweep"),
                                ("solenoid_step", "s", "solenoid-step tests")):
        rs = [r for r in results if r.scenario.kind == kind and not r.error]
        if not rs:
            continue
        u = [r.scenario.U_input for r in rs]
        ax.plot(u, [to_lpm(r.scenario.measured.Q_total) for r in rs], marker, mfc="none",
                color="C0", label=f"measured, {label}")
        groups: dict[str, list] = {}
        for r in rs:
            role = roles.get((r.name, "Q_total"), "held-out") if roles else "held-out"
            groups.setdefault(role, []).append(r)
        for role, members in groups.items():
            color, text = _ROLE_STYLE[role]
            ax.plot([r.scenario.U_input for r in members],
                    [to_lpm(r.simulated["Q_total"]) for r in members], marker, ms=4,
                    color=color, label=f"pvgraph, {label}" + (f" ({text})" if roles else ""))
    ax.set_xlabel("PVE input voltage U [V]")
    ax.set_ylabel("total flow Q_v [L/min]")
    ax.set_title("PVG 32 steady flow vs input voltage (cf. report fig. 4.39)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    return _save(fig, path)


def plot_cross_validation(records, path):
    """Held-out errors of a leave-one-group-out cross-validation, one row per grouping.

    ``records``: ``{grouping, scenario, quantity, error, role, ...}`` dicts (bar, L/min). Left:
    flow error against scenario with the +-1 L/min band; right: Pf, Pm, Pb errors with the
    +-2 bar band. Held-out values are filled, fitted ones hollow, trivial ones grey.
    """
    groupings = list(dict.fromkeys(r["grouping"] for r in records))
    fig, axes = plt.subplots(len(groupings), 2, figsize=(11, 3.3 * len(groupings)),
                             squeeze=False)
    for row, g in zip(axes, groupings):
        recs = [r for r in records if r["grouping"] == g and r["error"] is not None]
        names = list(dict.fromkeys(r["scenario"] for r in recs))
        pos = {n: k for k, n in enumerate(names)}
        for ax, quantities, band, unit in ((row[0], ("Q_total",), 1.0, "L/min"),
                                           (row[1], ("Pf", "Pm", "Pb"), 2.0, "bar")):
            ax.axhspan(-band, band, color="C2", alpha=0.12, label=f"+-{band:g} {unit}")
            for k, q in enumerate(quantities):
                for role in ("held-out", "fit", "trivial"):
                    pts = [r for r in recs if r["quantity"] == q and r["role"] == role]
                    if not pts:
                        continue
                    color = "0.5" if role == "trivial" else f"C{3 + k}"
                    ax.plot([pos[r["scenario"]] + 0.15 * (k - 1) for r in pts],
                            [r["error"] for r in pts], "o", color=color,
                            mfc=color if role == "held-out" else "none",
                            label=f"{q} {role}")
            ax.set_xticks(range(len(names)))
            ax.set_xticklabels(names, rotation=60, fontsize=7)
            ax.set_ylabel(f"predicted - measured [{unit}]")
            ax.set_title(f"leave one {g} group out", fontsize=9)
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize=6, ncol=2)
    fig.suptitle("PVG 32 cross-validation: held-out errors (filled), fitted (hollow)",
                 fontsize=10)
    return _save(fig, path)


def plot_step_traces(results, path):
    """Pressure drop over L3 after the solenoid step, 8 dynamic tests (report fig. 4.48)."""
    rs = [r for r in results if r.scenario.solenoid_event in ("opening", "closing")
          and not r.error]
    if not rs:
        fig, ax = plt.subplots()
        ax.text(0.5, 0.5, "no solenoid-step scenario in this run", ha="center")
        return _save(fig, path)
    cols = 2
    rows = int(np.ceil(len(rs) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(9, 2.2 * rows), sharex=True, squeeze=False)
    for ax, r in zip(axes.flat, rs):
        s = r.scenario
        ax.plot(r.trace_t, to_bar(r.trace_dp_L3), color="C3", label="pvgraph Pf - Pb")
        ax.axhline(to_bar(s.measured.Pf - s.measured.Pb), color="C0", ls="--",
                   label="measured steady Pf - Pb")
        ax.set_title(f"{r.name}: L2 {s.solenoid_event}, U = {s.U_input} V", fontsize=9)
        ax.set_ylim(0, 80)
        ax.grid(True, alpha=0.3)
    for ax in axes.flat[len(rs):]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("time after the step [s]")
    for ax in axes[:, 0]:
        ax.set_ylabel("[bar]")
    fig.suptitle("Pressure drop over L3 after the solenoid step (cf. report fig. 4.48)",
                 fontsize=10)
    return _save(fig, path)


def plot_step_comparison(traces, path, *, title="Step responses"):
    """Pressure drop over L3 after the solenoid step for model variants, one panel per test.

    ``traces``: ``{test: {label: ScenarioResult}}``; the measured steady value is dashed. Each
    label's legend entry gives its worst deviation from the final value 0.5 s after the step.
    """
    tests = list(traces)
    rows = int(np.ceil(len(tests) / 2))
    fig, axes = plt.subplots(rows, 2, figsize=(9, 2.4 * rows + 0.6), sharex=True, squeeze=False)
    for ax, test in zip(axes.flat, tests):
        for k, (label, r) in enumerate(traces[test].items()):
            if r.error:
                continue
            ax.plot(r.trace_t, to_bar(r.trace_dp_L3), color=f"C{3 + k}",
                    label=f"{label}: {to_bar(r.settle_deviation):.2f} bar after 0.5 s")
        s = next(iter(traces[test].values())).scenario
        ax.axhline(to_bar(s.measured.Pf - s.measured.Pb), color="C0", ls="--", lw=1)
        ax.set_title(f"{test}: L2 {s.solenoid_event}", fontsize=9)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=6)
    for ax in axes.flat[len(tests):]:
        ax.axis("off")
    for ax in axes[-1]:
        ax.set_xlabel("time after the step [s]")
    for ax in axes[:, 0]:
        ax.set_ylabel("Pf - Pb [bar]")
    fig.suptitle(title, fontsize=10)
    return _save(fig, path)


def draw_circuit(circuit, path, *, fmt="png"):
    """Draw a circuit's components and connections (networkx + matplotlib, or Graphviz DOT)."""
    import networkx as nx

    from .compiler import _flatten

    leaves = _flatten(circuit)
    graph = nx.Graph()
    for p, comp in leaves:
        graph.add_node(p, kind=type(comp).__name__)
    node_of = {}
    for p, comp in leaves:
        for port in comp.ports:
            node_of[(id(comp), port)] = p

    def walk(c, prefix):
        for refs in c._connections:
            ends = []
            for r in refs:
                ends.extend(_leaf_ports(r))
            owners = [node_of[(id(o), n)] for o, n in ends if (id(o), n) in node_of]
            for a, b in zip(owners, owners[1:]):
                graph.add_edge(a, b)
        for child in c._components.values():
            if hasattr(child, "_connections"):
                walk(child, prefix)

    walk(circuit, "")
    if fmt == "dot":
        lines = ["graph circuit {", "  node [shape=box, fontsize=9];"]
        for n, data in graph.nodes(data=True):
            lines.append(f'  "{n}" [label="{n}\\n{data["kind"]}"];')
        for a, b in graph.edges():
            lines.append(f'  "{a}" -- "{b}";')
        lines.append("}")
        with open(path, "w") as f:
            f.write("\n".join(lines) + "\n")
        return path
    fig, ax = plt.subplots(figsize=(12, 9))
    pos = nx.kamada_kawai_layout(graph) if graph.number_of_nodes() > 1 else {
        n: (0, 0) for n in graph}
    groups = sorted({n.split(".")[0] if "." in n else n for n in graph})
    colour = {g: f"C{k % 10}" for k, g in enumerate(groups)}
    nx.draw_networkx_edges(graph, pos, ax=ax, alpha=0.4)
    nx.draw_networkx_nodes(graph, pos, ax=ax, node_size=60,
                           node_color=[colour[n.split(".")[0]] for n in graph])
    nx.draw_networkx_labels(graph, pos, ax=ax, font_size=6,
                            labels={n: n.split(".", 1)[-1] for n in graph})
    ax.set_title(f"{circuit.name}: {graph.number_of_nodes()} components")
    ax.axis("off")
    return _save(fig, path)


def _leaf_ports(ref):
    """The leaf (component, port) pairs an exposed port stands for."""
    owner = ref.owner
    if hasattr(owner, "_exposed"):
        inner, _ = owner._exposed[ref.name]
        return _leaf_ports(inner)
    return [(owner, ref.name)]


def plot_bode(freq_hz, mag_db, phase_deg, path, *, labels=None, title="Bode plot"):
    """Bode magnitude and phase of one or more responses (lists of arrays)."""
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    labels = labels or [None] * len(mag_db)
    for m, ph, lab in zip(mag_db, phase_deg, labels):
        a1.semilogx(freq_hz, m, label=lab)
        a2.semilogx(freq_hz, ph, label=lab)
    a1.set_ylabel("magnitude [dB]")
    a2.set_ylabel("phase [deg]")
    a2.set_xlabel("frequency [Hz]")
    for a in (a1, a2):
        a.grid(True, which="both", alpha=0.3)
    if any(labels):
        a1.legend(fontsize=7)
    a1.set_title(title)
    return _save(fig, path)


def plot_step_response(curves, path, *, ylabel="", title="Step response"):
    """Step responses: ``curves`` is a list of (t, y, label)."""
    fig, ax = plt.subplots(figsize=(7, 4))
    for t, y, lab in curves:
        ax.plot(t, y, label=lab)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(title)
    return _save(fig, path)


def plot_opening_areas(tables, path, *, title="Opening areas"):
    """Opening area [mm^2] against spool position [mm], one line per table.

    ``tables`` holds objects with ``name``, ``x`` [m] and ``area`` [m^2] (e.g.
    :class:`circuits.pvg32.tables.AreaTable`); the lines carry the tables' names.
    """
    fig, ax = plt.subplots(figsize=(7, 4))
    for tab in tables:
        ax.plot(np.asarray(tab.x) * 1e3, np.asarray(tab.area) * 1e6, label=tab.name)
    ax.set_xlabel("spool position [mm]")
    ax.set_ylabel("opening area [mm^2]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(title)
    return _save(fig, path)
