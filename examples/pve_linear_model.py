"""The PVE + main spool position loop, linearised and tuned: report sections 4.8-4.9 redone.

Models of the same loop (x_set -> PVE controller -> solenoid valves -> chambers V4/V5 -> main
spool, LVDT feedback):

1. **pvgraph automatic**: the nonlinear PVE + PVB modules of ``pvgraph.circuits.pvg32`` on a bench of
   ideal pressure sources, linearised by :func:`pvgraph.analysis.linearize_circuit` at a steady
   state. The loop is opened exactly in the linear model (the set point enters only through
   e = x_set - x_meas, :meth:`LinearModel.open_loop`), which gives margins and root loci.
2. **table 4.15**: the report's hand-derived transfer functions (4.8.2-4.8.4, eq. 4.136-4.153)
   rebuilt with python-control. The table is garbled in the text; :func:`table_4_15` holds the
   readings of it, and the "complete" hand model: the same blocks with consistent gains and the
   chamber's displacement flow A_m dx_m/dt, which eq. 4.147 drops.
3. **nonlinear**: the bench simulated through the 3.5 mm step of figure 4.62.

Then the proportional gain of the loop (the PVE's duty-cycle slope, 70 %/mm, eq. 4.115) is
chosen from the Bode plot for a 60 deg phase margin and checked on the nonlinear model with
``pve.duty_gain`` scaled by it (figure 4.64). ``docs/pve_linear_model.md`` discusses the numbers.

Bench, not rig: the report's linear model is the PVE and main spool alone with the pressure
drop over the main spool held constant (K_Pkls, eq. 4.135) and the flow forces neglected
(4.8.1). Ideal pressures at P (pump), A (load) and B (return) give exactly the constant drop,
while the compensator and the flow forces stay in the model.

Operating point: the spool held at the end of the step, x_set = 3.5 mm (x_m = 3.47 mm). Not
neutral: the centring spring's preload reverses there (65 N over its 10 um smoothing band, a
local stiffness 1800 times k_m), so a model linearised at x_m = 0 holds only within microns.
At 3.5 mm the duty cycles are 44 % (port A valves) and 13 % (port B valves), inside their
0-100 % limits, and the metering edges are open past their 1.5 mm overlap; overshoot and
settling, which the report's metrics describe, happen around this point. A second point at
mid-step (1.75 mm) shows how little the numbers depend on the choice.

Run: ``python examples/pve_linear_model.py [outdir]`` (writes pve_*.png there; default examples/output/).
"""

from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

try:
    import control  # noqa: E402
except ImportError:
    sys.exit("examples/pve_linear_model.py needs python-control: pip install \"pvgraph[control]\"")
import numpy as np  # noqa: E402

from pvgraph.circuits.pvg32.modules import build_pvb, build_pve  # noqa: E402
from pvgraph.circuits.pvg32.parameters import PVG32Params, report_tuned  # noqa: E402
from pvgraph.components.hydraulic import Tank  # noqa: E402
from pvgraph.components.signal import Constant  # noqa: E402
from pvgraph import Circuit  # noqa: E402
from pvgraph.analysis import linearize_circuit, steady_state  # noqa: E402
from pvgraph.simulate import simulate  # noqa: E402
from pvgraph.units import bar, mm  # noqa: E402

X_STEP = mm(3.5)          # [m] set-point step of figure 4.62
X_OP = X_STEP             # [m] operating point: the spool held at the end of the step
X_MID = mm(1.75)          # [m] second operating point, mid-step, to show the sensitivity
SMALL_STEP = mm(0.1)      # [m] small step for the linear-vs-nonlinear check
P_PUMP = bar(45.0)        # [Pa] pump pressure on the bench (LS + about 15 bar, 2.2)
P_LOAD = bar(30.0)        # [Pa] fed work port A
P_RETURN = bar(5.0)       # [Pa] return work port B
T_END = 0.25              # [s] figure 4.62 shows 0.25 s after the step
T_SIM = 0.6               # [s] simulated, so that the step metrics see the response settle
T_METRICS = np.linspace(0.0, 1.0, 20001)   # [s] time grid of the linear models' step metrics
REPORT_GAIN = 0.3         # P controller of figure 4.64
TARGET_PM = 60.0          # [deg] phase margin the tuned gain is chosen for

X = "pvb.main_spool.flange.x"
X_MEAS = "pve.lvdt.y"
U = "x_set"

# Report section 4.9 and figure 4.63 (c_vm = 2500 N s/m, table 4.15)
REPORT = {"rise_time": 0.0079, "settling_time": 0.0619, "overshoot": 27.7916, "ess": 4.0,
          "gm_db": 9.91, "w_gm": 214.0, "pm": 49.7, "w_pm": 87.5}

# Table 4.15 constants (4.8.2): bulk modulus, V4, NC/NO gains per % duty cycle and their
# pressure slopes, the common 3 ms valve lag, spool mass (0.185 + 1.569 kg lever), spring,
# A_m (eq. 4.92), K_input as printed, LVDT (eq. 4.113) and the duty slope 70 %/mm (eq. 4.115).
T415 = dict(beta=7000e5, V4=1.29e-5, K_NC=3e-7, K_NO=1.7e-7, K_NC_QP=8.8e-12,
            K_NO_QP=8.3e-12, tau=0.003, M_m=1.754, k_m=3695.0, A_m=254e-6, K_input=0.0028,
            K_lvdt=0.945, tau_lvdt=0.0059, K_DT=70.0 / mm(1.0))


#: where the figures go unless a folder is given: examples/output/, not the repository root
OUTPUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "output")


# ------------------------------------------------------------------------------------------
# Table 4.15, rebuilt

def table_4_15(c_vm: float = 2500.0, variant: str = "evaluated") -> dict:
    """The report's linear model (table 4.15, fig. 4.59) as python-control transfer functions.

    ``G_spool = 1/(M_m s^2 + c_vm s + k_m)``, ``G_lvdt = K_lvdt/(tau_lvdt s + 1)`` and
    ``G_pve = A_m K_Peq`` with ``K_Peq = K3 (K1 - K5) / (1 + K3 (K2 - K4))`` (eq. 4.149),
    ``K1 = K_NC/(tau s + 1)``, ``K2 = K_NC-QP``, ``K3 = beta/(V4 s)``, ``K4 = K_NO-QP``,
    ``K5 = K_NO/(tau s + 1)``. Variants:

    ``constants``  the formula with the printed constants, as written (no duty-cycle gain:
                   K_NC is per % of duty cycle, so x_error enters as if in %);
    ``printed``    the printed result ``G_pve = 102.4e9 / ((s + 0.33e3)(s + 0.027e3))``;
    ``evaluated``  ``printed`` with ``G_input = K_input = 0.0028`` in series in the forward
                   path: the only reading that reproduces both stability statements of 4.8.4
                   and the axes of figures 4.60/4.61 (see docs/pve_linear_model.md);
    ``corrected``  dimensionally consistent: the duty slope K_DT = 70 %/mm in series, and the
                   NC and NO contributions adding (a higher duty cycle opens NC and closes NO;
                   a higher P4 cuts the NC inflow and raises the NO outflow);
    ``complete``   ``corrected`` plus the flow the moving spool displaces from the chamber,
                   ``A_m dx_m/dt`` in eq. 4.103, which eq. 4.147 drops: the spool's velocity
                   then feeds back through the chamber pressure,
                   ``x_m = G_spool A_m P4``, ``P4 = beta/(V4 s + beta K_QP) (Q_v - A_m s x_m)``.

    Returns the blocks and ``forward`` (x_error -> x_m), ``loop`` (forward * G_lvdt) and
    ``closed`` (x_set -> x_m, negative feedback through the LVDT, fig. 4.59).
    """
    c = T415
    s = control.tf("s")
    spool = 1 / (c["M_m"] * s ** 2 + c_vm * s + c["k_m"])
    lvdt = c["K_lvdt"] / (c["tau_lvdt"] * s + 1)
    lag = 1 / (c["tau"] * s + 1)
    k3 = c["beta"] / (c["V4"] * s)
    if variant == "constants":
        pve = c["A_m"] * k3 * (c["K_NC"] - c["K_NO"]) * lag / (
            1 + k3 * (c["K_NC_QP"] - c["K_NO_QP"]))
        forward = pve * spool
    elif variant in ("printed", "evaluated"):
        pve = 102.4e9 / ((s + 0.33e3) * (s + 0.027e3))
        if variant == "evaluated":
            pve = c["K_input"] * pve
        forward = pve * spool
    elif variant in ("corrected", "complete"):
        flow = c["K_DT"] * (c["K_NC"] + c["K_NO"]) * lag           # Q_v / x_error
        chamber = c["beta"] / (c["V4"] * s + c["beta"] * (c["K_NC_QP"] + c["K_NO_QP"]))
        pve = c["A_m"] * chamber * flow
        if variant == "corrected":
            forward = pve * spool
        else:
            forward = flow * control.feedback(c["A_m"] * chamber * spool, c["A_m"] * s)
    else:
        raise ValueError(f"table_4_15: unknown variant {variant!r}; use 'constants', "
                         f"'printed', 'evaluated', 'corrected' or 'complete'")
    forward = control.minreal(forward, verbose=False)
    loop = control.minreal(forward * lvdt, verbose=False)
    return {"spool": spool, "pve": control.minreal(pve, verbose=False), "lvdt": lvdt,
            "forward": forward, "loop": loop, "closed": control.feedback(forward, lvdt)}


# ------------------------------------------------------------------------------------------
# pvgraph: the bench, its linear model and nonlinear steps
def with_duty_gain(p: PVG32Params, factor: float) -> PVG32Params:
    """``p`` with the PVE's duty-cycle slope (the loop's P gain, eq. 4.115) scaled."""
    return p.model_copy(update={"pve": p.pve.model_copy(
        update={"duty_gain": factor * p.pve.duty_gain})})


def with_spool_damping(p: PVG32Params, c_vm: float) -> PVG32Params:
    """``p`` with the main spool's viscous friction c_vm [N s/m] (4.8.4: 25 -> 2500)."""
    return p.model_copy(update={"main_spool": p.main_spool.model_copy(
        update={"viscous_friction": c_vm})})


def with_nc_delay(p: PVG32Params, tau: float) -> PVG32Params:
    """``p`` with the NC valves' switching lag [s] (4.5.5: 20 ms; the linear model 4.8.2: 3 ms)."""
    upd = {k: getattr(p.pve, k).model_copy(update={"switching_delay": tau})
           for k in ("nc1", "nc3")}
    return p.model_copy(update={"pve": p.pve.model_copy(update=upd)})


def voltage_for(p: PVG32Params, x_set: float) -> float:
    """The PVE input voltage commanding ``x_set`` (eq. 4.109-4.110 inverted) [V]."""
    return (x_set - p.pve.input_offset) / p.pve.input_gain * p.rig.supply_voltage


def build_bench(p: PVG32Params, x_set: float) -> Circuit:
    """PVB + PVE between ideal pressures: pump at P, load at A, return at B, tank at T."""
    c = Circuit("pve_bench")
    pvb = c.add("pvb", build_pvb(p))
    pve = c.add("pve", build_pve(p))
    pump = c.add("pump", Tank(p0=P_PUMP))
    load = c.add("load", Tank(p0=P_LOAD))
    ret = c.add("return", Tank(p0=P_RETURN))
    tank = c.add("tank", Tank(p0=p.tank_pressure))
    u = c.add("U", Constant(k=voltage_for(p, x_set)))
    c.connect(pump.port, pvb.P)
    c.connect(load.port, pvb.A)
    c.connect(ret.port, pvb.B)
    c.connect(tank.port, pvb.T, pve.T)
    c.connect(pvb.spool, pve.spool)
    c.connect(u.y, pve.U)
    return c


def automatic_model(p: PVG32Params, x_op: float = X_OP):
    """``(closed, open, op)``: the bench linearised at ``x_set = x_op``; input ``x_set``,
    outputs the spool position and the LVDT reading; ``open`` has the comparator removed."""
    def build(u):
        return build_bench(p, u[U])
    op = steady_state(build({U: x_op}).compile())
    closed = linearize_circuit(build, {U: x_op}, [X, X_MEAS], op=op, du={U: 1e-7})
    return closed, closed.open_loop(U, X_MEAS), op


def nonlinear_step(p: PVG32Params, x_from: float, x_to: float, t: np.ndarray) -> np.ndarray:
    """Spool position [m] after a set-point step ``x_from -> x_to`` at t = 0, from the
    steady state at ``x_from``."""
    op = steady_state(build_bench(p, x_from).compile())
    sol = simulate(build_bench(p, x_to).compile(), float(t[-1]), rtol=1e-6, t_eval=t, y0=op.y)
    return np.asarray(sol[X])


# ------------------------------------------------------------------------------------------
# Loop analysis helpers (python-control)
def _tf_margins(loop) -> dict:
    gm, pm, wg, wp = control.margin(loop)
    return {"gm_db": float(20 * np.log10(gm)), "w_gm": float(wg), "pm": float(pm),
            "w_pm": float(wp)}


def _lm_margins(opened) -> dict:
    m = opened.margins(X_MEAS, U)
    return {"gm_db": m.gain_db, "w_gm": m.w_gain, "pm": m.phase, "w_pm": m.w_phase}


def _metrics(sys_or_y, t=None, reference=X_STEP) -> dict:
    """Rise (10-90 %), 2 % settling, overshoot (MATLAB stepinfo's definitions, which 4.9's
    numbers follow) and the steady error against the set point."""
    info = (control.step_info(sys_or_y, t) if t is not None
            else control.step_info(sys_or_y, T_METRICS))
    final = info["SteadyStateValue"] / (reference if t is not None else 1.0)
    return {"rise_time": float(info["RiseTime"]), "settling_time": float(info["SettlingTime"]),
            "overshoot": float(info["Overshoot"]), "ess": float(abs(1.0 - final) * 100.0)}


def critical_gain(loop, k_max: float = 1e3) -> float:
    """Smallest gain K > 0 at which K * loop (negative unity feedback) has a pole in the right
    half plane: scanned on a root locus (``control.root_locus_map``), then bisected."""
    def unstable(k):
        return np.max(control.root_locus_map(loop, gains=[k]).loci.real) > 0.0
    gains = np.logspace(-3, np.log10(k_max), 121)
    real = np.max(control.root_locus_map(loop, gains=gains).loci.real, axis=1)
    bad = np.flatnonzero(real > 0.0)
    if len(bad) == 0:
        return np.inf
    hi = gains[bad[0]]
    lo = gains[bad[0] - 1] if bad[0] > 0 else 0.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if unstable(mid) else (mid, hi)
    return float(0.5 * (lo + hi))


def loop_margins(opened, gain: float):
    """Margins of ``gain`` times the automatic model's loop. Closing the loop with ``gain`` and
    opening it again leaves ``A`` unchanged and scales the input: ``gain * L(s)``."""
    return opened.feedback(U, X_MEAS, gain).open_loop(U, X_MEAS).margins(X_MEAS, U)


def gain_for_phase_margin(loop, pm_target: float) -> float:
    """The P gain giving phase margin ``pm_target`` [deg], read off the Bode plot: at the
    first frequency where the loop's phase reaches ``pm_target - 180`` deg the gain must make
    the magnitude one."""
    w = np.logspace(-1, 4, 20001)
    h = np.asarray(control.frequency_response(loop, w).complex).reshape(-1)
    phase = np.degrees(np.unwrap(np.angle(h)))
    k = np.flatnonzero(phase <= pm_target - 180.0)[0]
    frac = (pm_target - 180.0 - phase[k - 1]) / (phase[k] - phase[k - 1])
    mag = np.exp(np.log(abs(h[k - 1])) + frac * (np.log(abs(h[k])) - np.log(abs(h[k - 1]))))
    return float(1.0 / mag)


# ------------------------------------------------------------------------------------------
def _plots(outdir, curves_step, curves_gain, bode, loci, poles_table, poles_auto):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pvgraph.plotting import plot_bode, plot_step_response

    def crop(curves):
        return [(tc[tc <= T_END], np.asarray(y)[tc <= T_END], lab) for tc, y, lab in curves]

    paths = {}
    paths["step"] = plot_step_response(
        crop(curves_step), os.path.join(outdir, "pve_step.png"), ylabel="main spool x_m [mm]",
        title="3.5 mm set-point step (report figure 4.62)")
    paths["gain"] = plot_step_response(
        crop(curves_gain), os.path.join(outdir, "pve_pgain.png"), ylabel="x_m / x_set [-]",
        title="P gain 1 vs lower gains (report figure 4.64)")
    w = bode["w"]
    paths["bode"] = plot_bode(w / (2 * np.pi), bode["mag"], bode["phase"],
                              os.path.join(outdir, "pve_bode.png"), labels=bode["labels"],
                              title="Loop x_error -> LVDT reading (report figure 4.63)")
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.5))
    for label, locus in loci.items():
        a1.plot(locus.real.ravel(), locus.imag.ravel(), ".", ms=2, label=label)
    a1.axvline(0.0, color="k", lw=0.6)
    a1.set_xlim(-1500, 600)
    a1.set_ylim(-1500, 1500)
    a1.set_xlabel("real [1/s]")
    a1.set_ylabel("imaginary [rad/s]")
    a1.set_title("root loci of K * loop, K = 0.001..100 (figure 4.65)")
    a1.legend(fontsize=7)
    for (label, poles), marker in zip(list(poles_table.items()) + list(poles_auto.items()),
                                      "xo+^sd"):
        a2.plot(poles.real, poles.imag, marker, label=label, mfc="none")
    a2.axvline(0.0, color="k", lw=0.6)
    a2.set_xlim(-1600, 400)
    a2.set_ylim(-500, 500)
    a2.set_xlabel("real [1/s]")
    a2.set_title("closed-loop poles (figures 4.60, 4.61)")
    a2.legend(fontsize=7)
    for a in (a1, a2):
        a.grid(True, alpha=0.3)
    fig.tight_layout()
    paths["poles"] = os.path.join(outdir, "pve_poles.png")
    fig.savefig(paths["poles"], dpi=110)
    plt.close(fig)
    return paths


def main(outdir=OUTPUT, *, verbose: bool = True) -> dict:
    outdir = str(outdir)
    os.makedirs(outdir, exist_ok=True)
    p = report_tuned()
    t = np.linspace(0.0, T_SIM, 1201)

    # --- table 4.15: stability with c_vm = 25 and 2500 (4.8.4, figures 4.60-4.61)
    variants = ("constants", "printed", "evaluated", "corrected", "complete")
    table = {(v, c): table_4_15(c, v) for v in variants for c in (25.0, 2500.0)}
    cl_poles = {k: np.asarray(control.poles(m["closed"])) for k, m in table.items()}
    t415 = table[("evaluated", 2500.0)]
    hand = table[("complete", 25.0)]     # the hand model with its missing term, c_vm as tuned

    # --- automatic linearisation (c_vm = 25 as validated; 2500 as the report's fix)
    closed, opened, op = automatic_model(p)
    closed_2500, opened_2500, _ = automatic_model(with_spool_damping(p, 2500.0))
    closed_mid, opened_mid, op_mid = automatic_model(p, X_MID)
    closed_nc3, opened_nc3, _ = automatic_model(with_nc_delay(p, T415["tau"]))
    L_auto = opened.siso(X_MEAS, U)
    wn, zeta, poles = closed.damping()

    # --- step responses: 3.5 mm (figure 4.62)
    x_nl = nonlinear_step(p, 0.0, X_STEP, t)
    x_auto = closed.step(t, X, U, X_STEP)
    x_t415 = control.step_response(X_STEP * t415["closed"], t).outputs
    x_hand = control.step_response(X_STEP * hand["closed"], t).outputs

    # --- small step at the operating point: the linear model's own validity
    x_small_nl = nonlinear_step(p, X_OP, X_OP + SMALL_STEP, t) - op[X]
    x_small_lin = closed.step(t, X, U, SMALL_STEP)

    # --- metrics
    res = {"x_op_mm": op[X] * 1e3, "x_set_op_mm": X_OP * 1e3,
           "duty_op_pct": (op["pve.controller.DT_A_pct"], op["pve.controller.DT_B_pct"])}
    res["metrics"] = {
        "report": {k: REPORT[k] for k in ("rise_time", "settling_time", "overshoot", "ess")},
        "table_4_15": _metrics(t415["closed"]),
        "hand_complete": _metrics(hand["closed"]),
        "automatic": _metrics(closed.siso(X, U)),
        "automatic_c2500": _metrics(closed_2500.siso(X, U)),
        "automatic_mid": _metrics(closed_mid.siso(X, U)),
        "automatic_nc3ms": _metrics(closed_nc3.siso(X, U)),
        "nonlinear": _metrics(x_nl, t),
    }
    res["margins"] = {
        "report": {k: REPORT[k] for k in ("gm_db", "w_gm", "pm", "w_pm")},
        "table_4_15": _tf_margins(t415["loop"]),
        "hand_complete": _tf_margins(hand["loop"]),
        "automatic": _lm_margins(opened),
        "automatic_c2500": _lm_margins(opened_2500),
        "automatic_mid": _lm_margins(opened_mid),
        "automatic_nc3ms": _lm_margins(opened_nc3),
    }

    # --- root locus: the gain at which the loop goes unstable
    k_crit = {"table_4_15": critical_gain(t415["loop"]),
              "hand_complete": critical_gain(hand["loop"]),
              "automatic": critical_gain(L_auto)}
    gains = np.logspace(-3, 2, 400)
    loci = {"table 4.15 (evaluated, c_vm 2500)": control.root_locus_map(
                t415["loop"], gains=gains).loci,
            "hand model complete (c_vm 25)": control.root_locus_map(
                hand["loop"], gains=gains).loci,
            "pvgraph automatic (c_vm 25)": opened.root_locus(X_MEAS, U, gains)[1]}

    # --- the P gain: the report's 0.3 and one chosen for a 60 deg phase margin
    k_design = gain_for_phase_margin(L_auto, TARGET_PM)
    gains_res = {}
    for label, k in (("report_0.3", REPORT_GAIN), ("design", k_design)):
        auto_k = opened.feedback(U, X_MEAS, k)
        t415_k = control.feedback(k * t415["forward"], t415["lvdt"])
        m_a = loop_margins(opened, k)
        gains_res[label] = {
            "gain": k,
            "automatic": {**_metrics(auto_k.siso(X, U)), "gm_db": m_a.gain_db,
                          "pm": m_a.phase, "w_pm": m_a.w_phase},
            "table_4_15": {**_metrics(t415_k), **_tf_margins(k * t415["loop"])},
            "hand_complete": {**_metrics(control.feedback(k * hand["forward"], hand["lvdt"])),
                              **_tf_margins(k * hand["loop"])},
        }
    # verify the design on the nonlinear model: the PVE's duty slope scaled by k_design
    p_k = with_duty_gain(p, k_design)
    closed_k, _, op_k = automatic_model(p_k)
    x_k_nl = nonlinear_step(p_k, X_OP, X_OP + SMALL_STEP, t) - op_k[X]
    x_k_lin = opened.feedback(U, X_MEAS, k_design).step(t, X, U, SMALL_STEP)
    x_k_big = nonlinear_step(p_k, 0.0, X_STEP, t)
    gains_res["design"]["nonlinear_small"] = _metrics(x_k_nl, t, SMALL_STEP)
    gains_res["design"]["nonlinear_3p5mm"] = _metrics(x_k_big, t)
    gains_res["design"]["linear_small"] = _metrics(x_k_lin, t, SMALL_STEP)
    res["gains"] = gains_res

    res.update({
        "table_poles": {f"{v}_c{int(c)}": cl_poles[(v, c)] for (v, c) in cl_poles},
        "table_rhp": {f"{v}_c{int(c)}": int(np.sum(cl_poles[(v, c)].real > 0))
                      for (v, c) in cl_poles},
        "auto_poles": poles, "auto_wn": wn, "auto_zeta": zeta,
        "auto_c2500_poles": closed_2500.poles(),
        "auto_mid_poles": closed_mid.poles(), "x_mid_op_mm": op_mid[X] * 1e3,
        "auto_nc3ms_poles": closed_nc3.poles(),
        "auto_dc_gain": float(closed.dc_gain()[0, 0]),
        "auto_open_loop_dc": float(opened.dc_gain()[1, 0]),
        "k_crit": k_crit, "k_design": k_design,
        "t": t, "x_nonlinear": x_nl, "x_automatic": x_auto, "x_table": x_t415,
        "x_hand": x_hand,
        "x_small_nonlinear": x_small_nl, "x_small_linear": x_small_lin,
        "x_design_small_nonlinear": x_k_nl, "x_design_small_linear": x_k_lin,
        "x_nonlinear_final_mm": float(x_nl[-1] * 1e3),
        "x_design_op_mm": op_k[X] * 1e3,
    })
    res["small_step_error"] = float(np.max(np.abs(x_small_lin - x_small_nl)) / SMALL_STEP)
    res["design_small_step_error"] = float(np.max(np.abs(x_k_lin - x_k_nl)) / SMALL_STEP)

    # --- plots
    ms = 1e3
    curves_step = [(t, x_nl * ms, "nonlinear (pvgraph)"),
                   (t, x_auto * ms, f"pvgraph automatic linear (op x_set {X_OP * ms:.1f} mm)"),
                   (t, x_t415 * ms, "table 4.15 (evaluated, c_vm 2500)"),
                   (t, x_hand * ms, "hand model complete (c_vm 25)"),
                   (t, np.full_like(t, X_STEP * ms), "x_set")]
    hand_03 = control.feedback(REPORT_GAIN * hand["forward"], hand["lvdt"])
    curves_gain = [
        (t, closed.step(t, X, U), "automatic, gain 1"),
        (t, opened.feedback(U, X_MEAS, REPORT_GAIN).step(t, X, U), "automatic, gain 0.3"),
        (t, opened.feedback(U, X_MEAS, k_design).step(t, X, U),
         f"automatic, gain {k_design:.2f} (PM {TARGET_PM:.0f} deg)"),
        (t, x_k_nl / SMALL_STEP, f"nonlinear, duty slope x {k_design:.2f}, 0.1 mm step"),
        (t, x_k_big / X_STEP, f"nonlinear, duty slope x {k_design:.2f}, 3.5 mm step"),
        (t, control.step_response(hand["closed"], t).outputs, "hand model complete, gain 1"),
        (t, control.step_response(hand_03, t).outputs, "hand model complete, gain 0.3"),
    ]
    w = np.logspace(-1, 4, 600)
    mags, phases, labels = [], [], []
    for label, loop in (("table 4.15 (evaluated)", t415["loop"]),
                        ("hand model complete (c_vm 25)", hand["loop"]),
                        ("pvgraph automatic", L_auto)):
        resp = control.frequency_response(loop, w)
        mags.append(20 * np.log10(np.abs(resp.complex).ravel()))
        phases.append(np.degrees(np.unwrap(np.angle(resp.complex).ravel())))
        labels.append(label)
    poles_table = {"table 4.15 c_vm 25": cl_poles[("evaluated", 25.0)],
                   "table 4.15 c_vm 2500": cl_poles[("evaluated", 2500.0)]}
    poles_auto = {"automatic c_vm 25": poles, "automatic c_vm 2500": closed_2500.poles()}
    res["paths"] = _plots(outdir, curves_step, curves_gain,
                          {"w": w, "mag": mags, "phase": phases, "labels": labels},
                          loci, poles_table, poles_auto)
    if verbose:
        _print(res)
    return res


def _print(res):
    cols = ("report", "table_4_15", "hand_complete", "automatic", "automatic_mid",
            "automatic_c2500", "automatic_nc3ms", "nonlinear")
    head = ("report 4.9", "t4.15", "hand compl", "auto", "auto 1.75", "auto c2500",
            "auto NC 3ms", "nonlinear")
    print(f"operating point x_set {res['x_set_op_mm']:.2f} mm: x_m {res['x_op_mm']:.3f} mm, "
          f"duty cycles {res['duty_op_pct'][0]:.1f} % / {res['duty_op_pct'][1]:.1f} %")
    print(f"{'':18s}" + "".join(f"{h:>12s}" for h in head))
    rows = (("rise time [s]", "rise_time", "metrics"), ("settling [s]", "settling_time",
            "metrics"), ("overshoot [%]", "overshoot", "metrics"), ("e_ss [%]", "ess",
            "metrics"), ("GM [dB]", "gm_db", "margins"), ("  at [rad/s]", "w_gm", "margins"),
            ("PM [deg]", "pm", "margins"), ("  at [rad/s]", "w_pm", "margins"))
    for name, key, group in rows:
        vals = [res[group].get(c, {}).get(key) for c in cols]
        print(f"{name:18s}" + "".join(f"{v:12.4g}" if v is not None else f"{'-':>12s}"
                                      for v in vals))
    print("closed-loop poles, table 4.15 (RHP count):")
    for k, v in res["table_poles"].items():
        print(f"  {k:16s} rhp {res['table_rhp'][k]}  " + " ".join(
            f"{z.real:.1f}{z.imag:+.1f}j" for z in v))
    print("automatic, dominant closed-loop poles (wn [rad/s], zeta):")
    for z, w, d in list(zip(res["auto_poles"], res["auto_wn"], res["auto_zeta"]))[:6]:
        print(f"  {z.real:9.2f} {z.imag:+9.2f}j  wn {w:8.2f}  zeta {d:6.3f}")
    print("critical gains (root locus):", {k: round(v, 3) for k, v in res["k_crit"].items()})
    for label, g in res["gains"].items():
        print(f"gain {g['gain']:.3f} ({label}):")
        for model in ("automatic", "table_4_15", "hand_complete"):
            m = g[model]
            print(f"  {model:14s} PM {m['pm']:6.1f} deg  GM {m['gm_db']:5.1f} dB  OS "
                  f"{m['overshoot']:5.1f} %  rise {m['rise_time']:.4f} s  settling "
                  f"{m['settling_time']:.4f} s")
    d = res["gains"]["design"]
    print(f"design check 0.1 mm step: linear OS {d['linear_small']['overshoot']:.1f} %, "
          f"nonlinear OS {d['nonlinear_small']['overshoot']:.1f} %, max difference "
          f"{res['design_small_step_error'] * 100:.1f} % of the step; 3.5 mm nonlinear OS "
          f"{d['nonlinear_3p5mm']['overshoot']:.1f} %")
    print(f"small step at the op (gain 1): max |linear - nonlinear| = "
          f"{res['small_step_error'] * 100:.1f} % of the step")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else OUTPUT)
