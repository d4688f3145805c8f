"""Plots with matplotlib: time series by name, Bode and step responses, circuit drawings.

All functions write a PNG (or SVG, by the file's extension) to the path given and return it;
they use the non-interactive Agg backend so they work on machines without a screen.
"""

from __future__ import annotations

import os

import numpy as np

from .errors import PvgraphError
from .units import display


class _NoMatplotlib:
    """``plt`` where matplotlib is not installed: a figure asked for says so (a DOT drawing
    needs no matplotlib)."""

    def __getattr__(self, name):
        raise PvgraphError('this figure is drawn with matplotlib, which is not installed: '
                           'pip install matplotlib')


try:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ModuleNotFoundError as exc:
    if exc.name != "matplotlib":
        raise
    plt = _NoMatplotlib()

__all__ = ["plot_solution", "draw_circuit", "plot_bode", "plot_step_response",
           "plot_opening_areas"]



#: file extensions naming a figure or drawing format, besides the one asked for
_FORMAT_SUFFIXES = ("png", "svg", "pdf", "dot", "gv", "jpg", "jpeg", "eps", "ps", "tif", "tiff")


def _save(fig, path, fmt=None):
    """Write ``fig`` to ``path`` itself, in ``fmt`` (default: the extension, else PNG)."""
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    fig.tight_layout()
    fmt = fmt or os.path.splitext(os.fspath(path))[1].lstrip(".").lower() or "png"
    try:
        fig.savefig(path, dpi=110, format=fmt)
    finally:
        plt.close(fig)
    return path


def plot_solution(sol, names, path, *, title=None, si=False):
    """One panel per unit: the named variables over time, in bar, L/min, mm (SI if ``si``)."""
    from .simulate import _name_list
    names = _name_list(names, "plot_solution: names")
    if not names:
        raise ValueError("plot_solution: names is empty; name at least one variable")
    if os.path.isdir(path):
        raise IsADirectoryError(f"plot_solution: path {os.fspath(path)!r} is a directory; give "
                                f"a file name in it (e.g. {os.path.join(path, 'plot.png')!r})")
    groups: dict[str, list[str]] = {}
    for n in names:
        groups.setdefault(sol.unit(n), []).append(n)
    fig, axes = plt.subplots(len(groups), 1, figsize=(8, 2.6 * len(groups)), sharex=True,
                             squeeze=False)
    for ax, (unit, members) in zip(axes[:, 0], groups.items()):
        label = display(1.0, unit, si)[1]
        for n in members:
            ax.plot(sol.t, display(sol[n], unit, si)[0], label=n)
        ax.set_ylabel(f"[{label}]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    axes[-1, 0].set_xlabel("time [s]")
    if title:
        axes[0, 0].set_title(title)
    return _save(fig, path)


#: how each domain's connections are drawn: (matplotlib colour, line style, DOT attributes)
_DOMAIN_STYLE = {
    "hydraulic": ("C0", "-", 'color="#1f77b4", penwidth=1.6'),
    "mechanical": ("0.3", "--", 'color="gray30", style=dashed'),
    "signal": ("C2", ":", 'color="#2ca02c", style=dotted'),
}


def _schematic(circuit):
    """Components, junctions and domain-tagged edges of a circuit, and its sub-circuit groups.

    Returns ``(nodes, edges, groups)``: nodes ``{id: (label, kind, group)}`` (kind is the class
    name, or ``"junction"``), edges ``[(a, b, domain, port at a, port at b)]`` (a junction's
    port name is empty), groups in depth-first order.
    """
    from .circuit import Circuit, _leaf_port, _leaves

    nodes, edges, groups = {}, [], [""]
    path_of = {}
    for path, comp in _leaves(circuit):
        group = path.rpartition(".")[0]
        nodes[path] = (path.rpartition(".")[2], type(comp).__name__, group)
        path_of[id(comp)] = path

    def walk(node, prefix):
        for k, refs in enumerate(node._connections):
            ends, ports = [], {}
            for r in refs:
                owner, port = _leaf_port(r)
                ends.append(path_of[id(owner)])
                ports.setdefault(ends[-1], []).append(port)
            domain = refs[0].port.domain.name
            label = {e: ",".join(p) for e, p in ports.items()}
            if len(set(ends)) > 2:
                junction = f"{prefix}#{k}"
                nodes[junction] = ("", "junction", prefix.rstrip("."))
                edges.extend((e, junction, domain, label[e], "") for e in dict.fromkeys(ends))
            elif len(set(ends)) == 2:
                a, b = dict.fromkeys(ends)
                edges.append((a, b, domain, label[a], label[b]))
        for name, child in node._components.items():
            if isinstance(child, Circuit):
                groups.append(f"{prefix}{name}")
                walk(child, f"{prefix}{name}.")
    walk(circuit, "")
    return nodes, edges, groups


def _layered_positions(nodes, edges, groups):
    """``{node: (x, y)}``: x the BFS layer along the connections, y within bands per group."""
    import networkx as nx

    g = nx.Graph()
    g.add_nodes_from(nodes)
    g.add_edges_from((a, b) for a, b, *_ in edges)
    glob = {}
    for part in nx.connected_components(g):
        start = next(n for n in nodes if n in part)
        glob.update(nx.single_source_shortest_path_length(g, start))
    layer = {}
    for grp in groups:           # layers inside each sub-circuit spread its parts apart
        inside = g.subgraph([n for n, v in nodes.items() if v[2] == grp])
        for part in nx.connected_components(inside):
            start = min(part, key=lambda n: (glob[n], str(n)))
            for n, d in nx.single_source_shortest_path_length(inside, start).items():
                layer[n] = glob[start] + d
    for n in nodes:
        layer.setdefault(n, glob[n])
    order = {grp: k for k, grp in enumerate(groups)}
    bands: dict[str, dict[int, list]] = {}
    for n, (_, _, grp) in nodes.items():
        bands.setdefault(grp, {}).setdefault(layer[n], []).append(n)
    pos, y0, spans = {}, 0.0, {}
    for grp in sorted(bands, key=lambda grp: order.get(grp, len(order))):
        columns = bands[grp]
        height = max(len(v) for v in columns.values())
        for x in sorted(columns):
            members = columns[x]
            # barycentre of the neighbours already placed: fewer crossings
            members.sort(key=lambda n: (sum(pos[m][1] for m in g[n] if m in pos)
                                        / max(1, sum(1 for m in g[n] if m in pos)))
                         if any(m in pos for m in g[n]) else y0)
            for k, n in enumerate(members):
                pos[n] = (float(x), -(y0 + 0.5 + k + 0.5 * (height - len(members))))
        spans[grp] = (y0, y0 + height)
        y0 += height + 0.8
    return pos, spans


def draw_circuit(circuit, path, *, fmt=None):
    """A layered schematic of a circuit: labelled component boxes, grouped by sub-circuit.

    Components are laid out in layers along their connections and in one band per
    sub-circuit; hydraulic connections are solid blue, mechanical dashed grey, signals dotted
    green; a connection of three or more ports meets at a junction dot. ``fmt`` is "png",
    "svg" (matplotlib) or "dot" (Graphviz, with a cluster per sub-circuit); by default the
    extension of ``path``.
    """
    path = os.fspath(path)
    if os.path.isdir(path):
        raise PvgraphError(f"draw_circuit: {path!r} is a folder; give the file to write "
                           f"(e.g. {os.path.join(path, circuit.name + '.png')!r})")
    suffix = os.path.splitext(path)[1].lstrip(".").lower()
    if fmt is not None and suffix in _FORMAT_SUFFIXES and suffix != fmt and \
            {suffix, fmt} != {"dot", "gv"}:
        raise ValueError(f"draw_circuit: fmt={fmt!r} but the file {path!r} is named .{suffix}; "
                         f"name it .{fmt} or leave fmt out (the format then comes from the "
                         f"extension)")
    fmt = fmt or ({"gv": "dot"}.get(suffix, suffix) or "png")
    nodes, edges, groups = _schematic(circuit)
    if fmt == "dot":
        os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
        return _write_dot(circuit, nodes, edges, groups, path)
    if fmt not in ("png", "svg"):
        raise ValueError(f"draw_circuit: format {fmt!r}; choose png, svg or dot")
    if isinstance(plt, _NoMatplotlib):
        plt.subplots        # noqa: B018  (raises: matplotlib is not installed)
    import matplotlib.patches as mpatches
    from matplotlib.lines import Line2D

    pos, spans = _layered_positions(nodes, edges, groups)
    width = max(x for x, _ in pos.values()) + 1 if pos else 1
    height = max(-y for _, y in pos.values()) + 1 if pos else 1
    fig, ax = plt.subplots(figsize=(min(4 + 2.0 * width, 60), min(1.5 + 0.55 * height, 80)))
    for k, (grp, (top, bottom)) in enumerate(spans.items()):
        if not grp:
            continue
        ax.add_patch(mpatches.FancyBboxPatch(
            (-0.6, -bottom + 0.1), width + 0.2, bottom - top - 0.2,
            boxstyle="round,pad=0.05", fc=f"C{k % 10}", alpha=0.07, ec=f"C{k % 10}", lw=0.8))
        ax.text(-0.55, -top - 0.05, grp, fontsize=8, va="top", ha="left", color=f"C{k % 10}",
                fontweight="bold")
    for a, b, domain, port_a, port_b in edges:
        colour, style, _ = _DOMAIN_STYLE.get(domain, ("k", "-", ""))
        (xa, ya), (xb, yb) = pos[a], pos[b]
        for (x0, y0), (x1, y1), port in (((xa, ya), (xb, yb), port_a),
                                         ((xb, yb), (xa, ya), port_b)):
            if port:        # the port's name beside its component, along the line
                ax.text(x0 + 0.28 * (x1 - x0), y0 + 0.28 * (y1 - y0), port, fontsize=5,
                        color=colour, ha="center", va="center", zorder=2,
                        bbox=dict(boxstyle="square,pad=0.05", fc="white", ec="none"))
        if xa == xb and abs(ya - yb) > 1.01:     # same column: bow around the boxes between
            ax.add_patch(mpatches.FancyArrowPatch(
                (xa, ya), (xb, yb), connectionstyle=f"arc3,rad={0.25 if ya > yb else -0.25}",
                arrowstyle="-", color=colour, ls=style, lw=1.2, zorder=1))
        else:
            ax.plot([xa, xb], [ya, yb], color=colour, ls=style, lw=1.2, zorder=1)
    for n, (label, kind, _) in nodes.items():
        x, y = pos[n]
        if kind == "junction":
            ax.plot(x, y, "o", color="0.2", ms=3, zorder=3)
            continue
        ax.text(x, y, f"{label}\n{kind}", ha="center", va="center", fontsize=6.5, zorder=4,
                bbox=dict(boxstyle="round,pad=0.3", fc="white", ec="0.3", lw=0.8))
    handles = [Line2D([], [], color=c, ls=st, label=d) for d, (c, st, _) in
               _DOMAIN_STYLE.items() if any(e[2] == d for e in edges)]
    if handles:
        ax.legend(handles=handles, loc="upper right", fontsize=7, frameon=False)
    n_comp = sum(1 for v in nodes.values() if v[1] != "junction")
    n_sub = len(groups) - 1
    ax.set_title(f"{circuit.name}: {n_comp} component{'s' * (n_comp != 1)}, {n_sub} "
                 f"sub-circuit{'s' * (n_sub != 1)}",
                 fontsize=10)
    ax.set_xlim(-0.8, width)
    ax.set_ylim(-height - 0.2, 0.6)
    ax.axis("off")
    return _save(fig, path, fmt)


def _write_dot(circuit, nodes, edges, groups, path):
    def q(text):
        return '"' + str(text).replace('"', r'\"') + '"'

    lines = [f"graph {q(circuit.name)} {{", "  rankdir=LR;",
             '  node [shape=box, style=rounded, fontsize=9, fontname="Helvetica"];']
    members: dict[str, list] = {}
    for n, (_, _, grp) in nodes.items():
        members.setdefault(grp, []).append(n)

    def emit(grp, indent):
        pad = "  " * indent
        for n in members.get(grp, []):
            label, kind, _ = nodes[n]
            if kind == "junction":
                lines.append(f"{pad}{q(n)} [shape=point, width=0.06];")
            else:
                lines.append(f"{pad}{q(n)} [label={q(label + chr(92) + 'n' + kind)}];")
        for sub in groups:
            if sub and sub.rpartition(".")[0] == grp and sub != grp:
                lines.append(f"{pad}subgraph {q('cluster_' + sub)} {{")
                lines.append(f"{pad}  label={q(sub.rpartition('.')[2])}; style=rounded; "
                             f"color=gray60;")
                emit(sub, indent + 1)
                lines.append(f"{pad}}}")
    emit("", 1)
    for a, b, domain, port_a, port_b in edges:
        ends = "".join(f", {key}={q(port)}" for key, port in (("taillabel", port_a),
                                                              ("headlabel", port_b)) if port)
        lines.append(f"  {q(a)} -- {q(b)} [{_DOMAIN_STYLE.get(domain, ('', '', ''))[2]}"
                     f"{ends}, labelfontsize=7];")
    lines.append("}")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    return path


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
    :class:`pvgraph.circuits.pvg32.tables.AreaTable`); the lines carry the tables' names.
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
