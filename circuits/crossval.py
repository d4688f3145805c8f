"""Fitted and predicted apart: the role of every lab value, identification and cross-validation.

Roles
    Every compared value (scenario x quantity) has a role:

    ``fit``       the value was used to identify a parameter of the model being judged;
    ``repeat``    a repeat of a fit: the value's model configuration (input voltage, L1 and L3
                  settings, final L2 state; the sweep's own L3 law) is that of a fitted value of
                  the same quantity, so the model's steady value is the fitted number itself
                  (the closing tests 3, 6, 9, 12 end in the configuration of the closed-L2
                  tests 1, 4, 7, 10). With L2 closed no oil passes L1 and the model's Pm is its
                  Pb (plus the return hose's drop where one is identified): a closed-L2 Pm whose
                  Pb is fitted, or a repeat, is a repeat too. Counted with the fit, never as
                  held-out;
    ``held-out``  predicted by parameters identified without that model configuration;
    ``trivial``   a value any model passes: the flows of the neutral sweep points (0 L/min) and
                  Q_branch with L2 closed (0).

    The saturated sweep point's flow is the pump's: ``fit`` where the pump flow was identified
    from it (the tuned preset's 16.3 L/min, 4.7.3), else ``held-out`` (a pump flow taken from
    elsewhere, e.g. the nominal 17 L/min of table 4.9, gives 16.93 L/min there, not 16.30).

    :func:`tuned_roles` gives the roles for the report's tuned preset (table 4.14 with the
    reconstructed A_H and the return line), whose provenance is written in
    :data:`TUNED_PROVENANCE`: 13 of its 17 non-neutral flows are ``fit`` (the 12 A_H anchors
    and the saturated sweep point), 4 ``held-out`` (the opening tests 2, 5, 8, 11).

    Two more labels appear among the acceptance targets of :mod:`pvgraph.circuits.validation`,
    not on lab values: ``model check`` (the model compared with itself, e.g. its PVP margin with
    its own spring law, or its load pressure with its own final value; nothing measured).

Identification (:func:`identify`)
    Everything the model takes from the lab data is re-identified from a training set of
    scenarios, by one fixed procedure:

    0. the hose from the junction of L1 and L3 to the Pb transducer, and that transducer's
       offset (``rig.return_hose_K``, ``rig.pb_sensor_offset``): with L2 closed Pm reads the
       junction, so Pm - Pb = offset' + Q_total / K_hose over the closed-L2 points (B.7);
    1. load laws, per orifice setting, from the training tests' measured Q and dp (report
       4.7.2, eq. 4.132): Q = K dp + b dp |dp| with b >= 0 (non-negative least squares) where
       the training data span two pressure levels, else Q = K dp (1 + beta dp) with beta the
       mean b/K of the L1/L3 settings fitted at two levels (the laminar Q = K dp where none);
    2. supply voltage U_s and the shape of the main-spool opening A_H (the cubic of
       :func:`pvgraph.circuits.pvg32.tables.main_spool_area`, with the report's dead band and 7 mm
       area fixed) by least squares on the training flows, with the spool travel commanded by
       the PVE (eq. 4.110, 4.133) and the drop the compensator holds;
    3. the full model's steady states at the training points: A_H refitted at the travel and
       main-spool drop the model actually settles at, the return-line constant from the mean
       Pb residual, the pump flow from the saturated points (none: the nominal 17 L/min of
       table 4.9), repeated until the return line and the pump flow move by less than 1e-4
       (two to four passes): the result does not depend on the values the base preset holds
       for them, which were tuned on all the data (the held-out group's too).

Cross-validation (:func:`cross_validate`)
    Leave one scenario group out (grouped by input voltage, or by load configuration),
    identify on the rest, predict the held-out group's steady states. Steady states
    (:func:`pvgraph.analysis.steady_state`) stand in for the 8-10 s simulations: they are what
    the lab tabulated. In a load-configuration fold the held-out orifice setting has no
    training data, so its load law comes from the held-out tests' own Q and dp; their Pf, Pm
    and Q_branch, which that law then fixes, are marked ``fit``.
"""

from __future__ import annotations

import math
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares, nnls

from pvgraph.analysis import steady_state
from pvgraph.analysis.sweep import MAX_PROCESS_WORKERS
from pvgraph.errors import PvgraphError
from pvgraph.units import bar, lpm, lpm_per_bar, to_bar, to_lpm

from .pvg32 import tables
from .pvg32.modules import A_H_FIT_DROP, A_H_FIT_POSITION_SCALE
from .pvg32.parameters import PVG32Params, report_initial, report_tuned, with_values
from .rig import build_rig, laminar_load, readings
from .scenarios import Scenario, all_scenarios, get_scenario

__all__ = ["ROLES", "ROLE_CODES", "QUANTITIES", "SATURATED", "TUNED_PROVENANCE", "role",
           "tuned_roles", "configuration", "Identification", "identify", "steady_values",
           "GROUPINGS", "CrossValidation", "cross_validate", "judge", "format_cross_validation",
           "shown_against", "fold_keys", "pvp_margin_reachable", "SETTLED_STEP", "STEADY_AT_END"]

ROLES = ("fit", "repeat", "held-out", "trivial")
#: one-letter codes of the roles in the printed tables
ROLE_CODES = {"fit": "f", "repeat": "r", "held-out": "h", "trivial": "t"}
QUANTITIES = ("Q_total", "Q_branch", "Pf", "Pm", "Pb")
#: Pump saturated: 4.7.3, the 16.3 L/min is reached below about 4.19 V (sweep-7, 3.94 V)
SATURATED = ("sweep-7",)
PRESSURE_TOL = bar(2.0)       # absolute; a 10 % band would allow 6.6 bar at 66 bar
FLOW_TOL = lpm(1.0)
STEADY_TOL = 1e-10
U_S_BOUNDS = (10.5, 12.5)     # [V] around the 12 V nominal battery (table 4.9)
MIN_SLOPE = 0.5               # [mm^2/mm] least slope of the fitted A_H (monotone opening)
#: step 3 of the identification is repeated until the return line and the pump flow move by
#: less than this fraction (at most MAX_STEADY_PASSES passes)
STEADY_PASS_TOL = 1e-4
MAX_STEADY_PASSES = 6

#: What the tuned preset took from the lab data: (parameter, [(scenario, quantity), ...]).
TUNED_PROVENANCE: tuple[tuple[str, tuple[tuple[str, str], ...]], ...] = (
    ("main_spool A_H shape and supply voltage (4.7.3, tables.MAIN_SPOOL_LAB_ANCHORS)",
     tuple((name, "Q_total") for _, _, name in tables.MAIN_SPOOL_LAB_ANCHORS)),
    ("rig.pump_flow 16.3 L/min (4.7.3: the saturated sweep)", (("sweep-7", "Q_total"),)),
    ("rig.return_line_K (Pb of the closed-L2 tests 1, 4, 7, 10)",
     tuple((f"test-{k}", "Pb") for k in (1, 4, 7, 10))),
    ("rig.L1.laminar_small, rig.L3.laminar_small (table 4.8 = test 2's Q/dp)",
     (("test-2", "Q_branch"), ("test-2", "Pm"), ("test-2", "Pf"))),
    ("rig.L1.laminar_large, rig.L3.laminar_large (table 4.8 = test 8's Q/dp, L3 within 0.3 %)",
     (("test-8", "Q_branch"), ("test-8", "Pm"), ("test-8", "Pf"))),
    # figure 4.32 fits Q_L2 against its drop Pf - Pm (eq. 4.132) over the L2-open points of
    # both groups: the measured Pf and Pm of those tests went into K_L2 as much as Q_branch
    ("rig.L2.laminar_open (table 4.8, figure 4.32: Q against Pf - Pm of the opening tests of "
     "both groups)",
     tuple((f"test-{k}", q) for k in (2, 5, 8, 11) for q in ("Q_branch", "Pf", "Pm"))),
)


def _is_neutral(s: Scenario) -> bool:
    return s.measured.Q_total == 0.0


def configuration(s: Scenario) -> tuple:
    """The model configuration of scenario ``s`` at the end of its run: (voltage sweep or step
    test, U, L1, L3, final L2 state). Scenarios with one configuration share every steady
    value of the model."""
    return (s.kind == "voltage_sweep",) + _config(s)


def role(s: Scenario, quantity: str, fitted: set) -> str:
    """The role of ``quantity`` of scenario ``s``, given the ``(scenario, quantity)`` pairs used
    for identification (module doc: roles are per model configuration)."""
    if quantity in ("Q_total", "Q_branch") and _is_neutral(s):
        return "trivial"
    if quantity == "Q_branch" and not s.l2_open_finally:
        return "trivial"
    if (s.name, quantity) in fitted:
        return "fit"
    cfg = configuration(s)
    same = {q for n, q in fitted if configuration(get_scenario(n)) == cfg}
    if quantity in same:
        return "repeat"
    if quantity == "Pm" and not s.l2_open_finally and "Pb" in same:
        return "repeat"
    return "held-out"


def tuned_roles() -> dict[tuple[str, str], str]:
    """``{(scenario, quantity): role}`` for the report's tuned preset."""
    fitted = {pair for _, pairs in TUNED_PROVENANCE for pair in pairs}
    return {(s.name, q): role(s, q, fitted) for s in all_scenarios() for q in QUANTITIES}


def pvp_margin_reachable(p: PVG32Params) -> dict:
    """The PVP margin P_p - P_LS [Pa] at which the report's PVP spool opens A3 to tank.

    Spring force over spool area at the 2 mm overlap (eq. 4.17-4.19, C.1.2): the margin the
    report's own parameters hold while the pump's excess flow is relieved, against the 15 bar
    of the data sheet (2.2).
    """
    pv = p.pvp
    at_rest = pv.spring_preload / pv.spool_area
    at_opening = (pv.spring_preload + pv.spring_rate * pv.tank_area_dead_band) / pv.spool_area
    return {"preload_only": at_rest, "at_A3_opening": at_opening}


# ------------------------------------------------------------------------------ steady states
def _config(s: Scenario) -> tuple:
    return (s.U_input, s.orifice_L1 or "small", s.orifice_L3, s.l2_open_finally)


def _solve(args):
    """Steady values (SI) and the spool's travel and drop for one rig configuration."""
    p, (U, L1, L3, l2) = args
    load = laminar_load(p, L1=L1, L3=L3, l2_open=l2, t_switch=None)
    system = build_rig(p, load=load, U_input=U).compile()
    try:
        op = steady_state(system, tol=STEADY_TOL)
    except PvgraphError as exc:
        return {"error": f"{type(exc).__name__}: {str(exc).splitlines()[0]}"}
    q2, q3 = op["load.L2.q"], op["load.L3.q"]
    return {"Q_total": q2 + q3, "Q_branch": q2,
            **readings(p, op["load.f.port.p"], op["load.m.port.p"], op["load.b.port.p"]),
            "x_m": op["pvg.pvb.main_spool.flange.x"],
            "drop": op["pvg.pvb.PK.port.p"] - op["load.f.port.p"],
            "relief": op["pvg.pvp.A3.q"], "P_T": op["pvg.T.p"]}


def steady_values(p: PVG32Params, scenarios: list[Scenario], pool=None, *,
                  sweep_load: dict | None = None) -> dict[str, dict]:
    """``{scenario: steady values}`` (SI); configurations shared by scenarios are solved once.

    ``sweep_load``: parameter updates (the sweep's own L3 law) for the voltage-sweep scenarios.
    """
    p_sweep = with_values(p, sweep_load) if sweep_load else p

    def key(s):
        return (s.kind == "voltage_sweep",) + _config(s)
    configs = sorted({key(s) for s in scenarios}, key=str)
    jobs = [(p_sweep if c[0] else p, c[1:]) for c in configs]
    out = list(pool.map(_solve, jobs)) if pool is not None else [_solve(j) for j in jobs]
    by_cfg = dict(zip(configs, out))
    return {s.name: by_cfg[key(s)] for s in scenarios}


# ------------------------------------------------------------------------------ identification
@dataclass
class Identification:
    """Parameters identified from a training set, and where each came from."""

    params: PVG32Params
    sources: dict[str, str]
    sweep_load: dict = field(default_factory=dict)   # L3 law of the voltage sweep
    fitted: set = field(default_factory=set)         # (scenario, quantity) pairs used
    wall_time: float = 0.0


def _l3_key(s: Scenario) -> str:
    # the sweep was run on another occasion and its L3 setting is not stated (scenarios module
    # doc): it gets a law of its own rather than the tests' "large"
    return "L3.sweep" if s.kind == "voltage_sweep" else f"L3.{s.orifice_L3}"


def _load_points(scenarios, meas=(0.0, 0.0)):
    """(dp [bar], Q [L/min], scenario, quantities) per orifice setting from measured values.

    ``meas`` = (c0 [bar], c1 [bar min/L]): the junction of L1 and L3 is at Pb + c0 + c1 Q_total
    (:func:`_fit_measurement`); (0, 0) = the junction is node b."""
    c0, c1 = meas
    pts: dict[str, list] = {}
    for s in scenarios:
        m = s.measured
        if _is_neutral(s):
            continue
        q_total, q_branch = to_lpm(m.Q_total), to_lpm(m.Q_branch)
        p_j = to_bar(m.Pb) + c0 + c1 * q_total
        pts.setdefault(_l3_key(s), []).append(
            (to_bar(m.Pf) - p_j, q_total - q_branch, s.name, ("Pf",)))
        if s.l2_open_finally:
            pts.setdefault(f"L1.{s.orifice_L1}", []).append(
                (to_bar(m.Pm) - p_j, q_branch, s.name, ("Q_branch", "Pm")))
            pts.setdefault("L2", []).append(
                (to_bar(m.Pf - m.Pm), q_branch, s.name, ("Q_branch", "Pf", "Pm")))
    return pts


def _fit_measurement(scenarios):
    """(c0 [bar], c1 [bar min/L], names): Pm - Pb = c0 + c1 Q_total by least squares over the
    closed-L2 points, where no flow passes L1 and Pm reads the junction of L1 and L3: c1 is the
    hose from the junction to the Pb transducer (``rig.return_hose_K`` = 1/c1), -c0 the Pb
    transducer's offset (``rig.pb_sensor_offset``). None where fewer than 3 points or one flow
    level."""
    pts = [s for s in scenarios if not s.l2_open_finally]
    q = np.array([to_lpm(s.measured.Q_total) for s in pts])
    if len(pts) < 3 or np.ptp(q) < 1.0:
        return None
    d = np.array([to_bar(s.measured.Pm - s.measured.Pb) for s in pts])
    c1, c0 = np.polyfit(q, d, 1)
    if c1 <= 0.0:
        return None
    return float(c0), float(c1), [s.name for s in pts]


def _fit_load_law(points, quadratic: bool = True) -> tuple[float, float, str]:
    """(K [L/(min bar)], b [L/(min bar^2)], law) through the origin; laminar unless
    ``quadratic`` and the points span two pressure levels."""
    dp = np.array([d for d, *_ in points])
    q = np.array([v for _, v, *_ in points])
    if quadratic and dp.max() > 1.3 * dp.min():
        (k, b), _ = nnls(np.column_stack([dp, dp * dp]), q)
        if k > 0.0:
            return float(k), float(b), "K dp + b dp^2"
    return float(q @ dp / (dp @ dp)), 0.0, "laminar"


def _fit_with_curvature(points, beta: float) -> tuple[float, float, str]:
    """(K, b = beta K, law): Q = K dp (1 + beta |dp|) through ``points`` by least squares in K,
    with the relative curvature ``beta`` [1/bar] given (taken from other settings)."""
    dp = np.array([d for d, *_ in points])
    q = np.array([v for _, v, *_ in points])
    g = dp * (1.0 + beta * np.abs(dp))
    k = float(q @ g / (g @ g))
    return k, k * beta, f"K dp (1 + beta dp), beta = {beta:.4f}/bar shared"


def _surrogate_x(U, Us, p: PVG32Params):
    e = p.pve
    return A_H_FIT_POSITION_SCALE * np.abs(e.input_gain * np.asarray(U) / Us + e.input_offset)


def _cubic(p: PVG32Params, shape):
    m = p.main_spool
    u_full = m.stroke_max - m.dead_band
    c2, c3 = shape
    c1 = (m.area_at_full_stroke - c2 * u_full**2 - c3 * u_full**3) / u_full
    return c1, c2, c3


def _area(p, shape, x):
    c1, c2, c3 = _cubic(p, shape)
    u = np.clip(np.abs(x) - p.main_spool.dead_band, 0.0, None)
    return c1 * u + c2 * u**2 + c3 * u**3


def _monotone_penalty(p, shape):
    c1, c2, c3 = _cubic(p, shape)
    u = np.linspace(0.0, p.main_spool.stroke_max - p.main_spool.dead_band, 23)
    slope_mm = 1e3 * (c1 + 2 * c2 * u + 3 * c3 * u**2)      # [mm^2/mm]
    return 100.0 * np.clip(MIN_SLOPE - slope_mm, 0.0, None)


_SHAPE_SCALE = np.array([1.0, 1e3])       # c2 [-], c3 [1/m]: comparable magnitudes in the fit


def _fit_shape_and_supply(p, U, Q, x_fixed=None, drop=None, fit_supply=True):
    """Least squares of A_H shape (and U_s) to flows Q [m^3/s] at voltages U."""
    cd, rho = p.discharge_coefficient, p.fluid.density
    shape0 = p.main_spool.opening_shape or (-0.3438, 322.9)
    q_scale = lpm(1.0)

    def resid(z):
        shape = tuple(z[-2:] * _SHAPE_SCALE)
        x = x_fixed if x_fixed is not None else _surrogate_x(U, z[0], p)
        dp = drop if drop is not None else A_H_FIT_DROP
        q = cd * _area(p, shape, x) * np.sqrt(2.0 * np.asarray(dp) / rho)
        return np.concatenate([(q - Q) / q_scale, _monotone_penalty(p, shape)])

    z0 = np.array(shape0) / _SHAPE_SCALE
    if fit_supply:
        z0 = np.concatenate([[p.rig.supply_voltage], z0])
        lo = [U_S_BOUNDS[0], -np.inf, -np.inf]
        hi = [U_S_BOUNDS[1], np.inf, np.inf]
        sol = least_squares(resid, z0, bounds=(lo, hi), x_scale=[0.5, 0.1, 0.1])
        return float(sol.x[0]), tuple(float(v) for v in sol.x[1:] * _SHAPE_SCALE)
    sol = least_squares(resid, z0)
    return None, tuple(float(v) for v in sol.x * _SHAPE_SCALE)


def _with_shape(p: PVG32Params, shape) -> PVG32Params:
    return p.model_copy(update={"main_spool": p.main_spool.model_copy(
        update={"opening_shape": tuple(shape)})})



def _steady_or_raise(p, points, pool, sweep_updates) -> dict:
    """The model's steady states at ``points``; a point without one stops the identification."""
    steady = steady_values(p, points, pool, sweep_load=sweep_updates)
    bad = [n for n, v in steady.items() if "error" in v]
    if bad:
        raise PvgraphError(f"identify: no steady state for {bad}: {steady[bad[0]]['error']}")
    return steady


def _shape_at_model_travel(p, U, Q, flow_pts, steady):
    """A_H's shape refitted at the spool travel and drop the model settles at (section 8b)."""
    x = np.array([abs(steady[s.name]["x_m"]) for s in flow_pts])
    drop = np.array([max(steady[s.name]["drop"], bar(0.5)) for s in flow_pts])
    _, shape = _fit_shape_and_supply(p, U, Q, x_fixed=x, drop=drop, fit_supply=False)
    return shape

def identify(train: list[Scenario], base: PVG32Params | None = None, *,
             loads_from: list[Scenario] = (), pool=None,
             load_law: str = "shared", measurement: bool = True,
             meter_out: str | None = None) -> Identification:
    """Identify the data-derived parameters from ``train`` (module doc, steps 1-3).

    ``loads_from``: scenarios whose Q and dp may supply the law of an orifice setting the
    training set does not exercise (their Pf, Pm, Q_branch are then marked ``fit``).
    ``load_law``: "quadratic" (Q = K dp + b dp |dp|), "laminar" (the report's Q = K dp) or
    "shared" (quadratic; a setting the training data show at one pressure level only takes
    the mean relative curvature b/K of the L1/L3 settings seen at two levels, instead of
    the laminar law).
    ``measurement``: identify the return hose and the Pb transducer offset (step 0) from the
    training set's closed-L2 points; False = ideal transducers, L1 and L3 end at node b.
    ``meter_out``: identify the return edges, together with the return line, from the training
    Pb (:func:`_fit_meter_out`) instead of the return line alone: "overlap" (an extra overlap,
    ``main_spool.meter_out_overlap``) or "ratio" (A_out = A_H (r0 + r1 u),
    ``main_spool.meter_out_area_ratio``); None = the report's one A_H for all four edges.
    """
    if load_law not in ("quadratic", "laminar", "shared"):
        raise PvgraphError(f"identify: load_law must be 'quadratic', 'laminar' or 'shared', not "
                           f"{load_law!r}")
    if meter_out not in (None, "overlap", "ratio"):
        raise PvgraphError(f"identify: meter_out must be None, 'overlap' or 'ratio', not "
                           f"{meter_out!r}")
    t0 = time.perf_counter()
    p = base or report_tuned()
    sources: dict[str, str] = {}
    fitted: set = set()
    updates = {}
    # 0. measurement: hose from the L1/L3 junction to the Pb transducer, and its offset
    meas = _fit_measurement(train) if measurement else None
    c0c1 = (0.0, 0.0)
    if meas is not None:
        c0, c1, names = meas
        c0c1 = (c0, c1)
        p = p.model_copy(update={"rig": p.rig.model_copy(update={
            "return_hose_K": lpm_per_bar(1.0 / c1), "pb_sensor_offset": bar(-c0)})})
        fitted.update((n, "Pm") for n in names)
        sources["rig.return_hose_K, rig.pb_sensor_offset"] = (
            f"Pm - Pb = {c0:.3f} bar + {c1:.4f} bar/(L/min) Q_total: hose "
            f"{1.0 / c1:.1f} L/(min bar), Pb offset {-c0:+.3f} bar from Pm - Pb of "
            f"{', '.join(names)}")
    elif measurement:
        sources["rig.return_hose_K, rig.pb_sensor_offset"] = "not identifiable: ideal"
    # 1. load laws
    pts_train, pts_other = _load_points(train, c0c1), _load_points(loads_from, c0c1)
    sweep_updates = {}
    keys = ("L1.small", "L1.large", "L3.small", "L3.large", "L3.sweep", "L2")
    beta = None
    if load_law == "shared":
        # relative curvature b/K of the rig's needle orifices (L1, L3) fitted at two levels
        ratios = []
        for key in keys[:5]:
            pts = pts_train.get(key) or pts_other.get(key)
            if pts:
                k, b, law = _fit_load_law(pts)
                if law != "laminar":
                    ratios.append(b / k)
        beta = float(np.mean(ratios)) if ratios else None
    for key in keys:
        pts, origin = pts_train.get(key), "training tests"
        if not pts and pts_other.get(key):
            pts, origin = pts_other[key], "the held-out tests' own Q/dp"
        if not pts:
            sources[key] = "table 4.8 (not exercised by the data)"
            continue
        k, b, law = _fit_load_law(pts, quadratic=load_law != "laminar")
        if beta is not None and law == "laminar" and key != "L2":
            k, b, law = _fit_with_curvature(pts, beta)
        names = sorted({n for *_, n, _ in pts})
        for *_, n, quantities in pts:
            fitted.update((n, q) for q in quantities)
        if key == "L2":
            updates["rig.L2.laminar_open"] = lpm_per_bar(k)
        elif key == "L3.sweep":
            sweep_updates = {"rig.L3.laminar_large": lpm_per_bar(k),
                             "rig.L3.quadratic_large": lpm(b) / bar(1.0) ** 2}
        else:
            orifice, size = key.split(".")
            updates[f"rig.{orifice}.laminar_{size}"] = lpm_per_bar(k)
            updates[f"rig.{orifice}.quadratic_{size}"] = lpm(b) / bar(1.0) ** 2
        sources[key] = (f"{law}, K = {k:.4f} L/(min bar)" + (f", b = {b:.2e} L/(min bar^2)"
                        if b else "") + f" from {origin} ({', '.join(names)})")
    p = with_values(p, updates)
    sweep_updates = sweep_updates or {"rig.L3.laminar_large": p.rig.L3.laminar_large,
                                      "rig.L3.quadratic_large": p.rig.L3.quadratic_large}
    # 2. supply voltage and A_H shape on the surrogate
    flow_pts = [s for s in train if not _is_neutral(s) and s.name not in SATURATED]
    sat_pts = [s for s in train if s.name in SATURATED]
    if len(flow_pts) < 3:
        raise PvgraphError(f"identify: need >= 3 unsaturated flow points, got "
                           f"{[s.name for s in flow_pts]}")
    U = np.array([s.U_input for s in flow_pts])
    Q = np.array([s.measured.Q_total for s in flow_pts])
    Us, shape = _fit_shape_and_supply(p, U, Q)
    p = _with_shape(with_values(p, {"rig.supply_voltage": Us}), shape)
    if not sat_pts:
        p = with_values(p, {"rig.pump_flow": report_initial().rig.pump_flow})
    # 3. the model's steady states at the training points: A_H at the travel the model
    # settles at, the return line from the mean Pb residual, the pump flow from the saturated
    # points; repeated until those two stop moving, so that what the identification returns
    # does not hang on the base's values of them (tuned on all the data, held-out groups too)
    pb_pts = [s for s in train if not _is_neutral(s)]
    for passes in range(1, MAX_STEADY_PASSES + 1):
        steady = _steady_or_raise(p, pb_pts, pool, sweep_updates)
        shape = _shape_at_model_travel(p, U, Q, flow_pts, steady)
        pb_res = np.mean([steady[s.name]["Pb"] - s.measured.Pb for s in pb_pts])
        overlap = None
        if meter_out:
            # the neutral points' trapped pressure follows P_T (the leak divider, docs
            # section 11) and not the meter-out edges: they separate the return line from
            # the edges
            neutral = [s for s in train if _is_neutral(s)]
            steady.update(steady_values(p, neutral, pool, sweep_load=sweep_updates))
            pb_res, overlap = _fit_meter_out(p, shape, pb_pts + neutral, steady, meter_out)
            fitted.update((s.name, "Pb") for s in neutral)
        q_ret = p.rig.pump_flow
        p_ret = q_ret / p.rig.return_line_K
        k_ret = q_ret / max(p_ret - pb_res, bar(0.1))
        updates = {"rig.return_line_K": k_ret}
        if overlap is not None:
            key = "meter_out_overlap" if meter_out == "overlap" else "meter_out_area_ratio"
            p = p.model_copy(update={"main_spool": p.main_spool.model_copy(
                update={key: overlap})})
            text = (f"{overlap * 1e3:.3f} mm" if meter_out == "overlap" else
                    f"r0 = {overlap[0]:.3f}, r1 = {overlap[1] * 1e-3:.3f} /mm")
            sources[f"main_spool.{key}"] = (f"{text} with the return line from Pb of "
                                            f"{', '.join(s.name for s in pb_pts)}")
        if sat_pts:
            dq = np.mean([s.measured.Q_total - steady[s.name]["Q_total"] for s in sat_pts])
            updates["rig.pump_flow"] = p.rig.pump_flow + dq
        moved = max(abs(k_ret / p.rig.return_line_K - 1.0),
                    abs(updates.get("rig.pump_flow", p.rig.pump_flow) / p.rig.pump_flow - 1.0))
        p = _with_shape(with_values(p, updates), shape)
        if moved <= STEADY_PASS_TOL:
            break
    if overlap is not None:
        # the edges and P_T move the spool's flow force and the PVE's drain: A_H once more at
        # the travel and drop of the model with them
        again = _steady_or_raise(p, flow_pts, pool, sweep_updates)
        shape = _shape_at_model_travel(p, U, Q, flow_pts, again)
        p = _with_shape(p, shape)
    fitted.update((s.name, "Q_total") for s in flow_pts + sat_pts)
    fitted.update((s.name, "Pb") for s in pb_pts)
    names = ", ".join(s.name for s in flow_pts)
    sources["rig.supply_voltage"] = f"{Us:.3f} V from the flows of {names}"
    sources["main_spool.opening_shape"] = (
        f"c2 = {shape[0]:.4f}, c3 = {shape[1]:.1f} /m from the same flows at the model's travel "
        f"and drop")
    sources["rig.return_line_K"] = (f"{k_ret / lpm_per_bar(1.0):.2f} L/(min bar) from Pb of "
                                    f"{', '.join(s.name for s in pb_pts)} ({passes} passes of "
                                    f"the model's steady states)")
    sources["rig.pump_flow"] = (
        f"{to_lpm(p.rig.pump_flow):.2f} L/min from " +
        (", ".join(s.name for s in sat_pts) if sat_pts else "table 4.9 (nominal 17 L/min: no "
                                                            "saturated point in the training set)"))
    return Identification(p, sources, sweep_updates, fitted, time.perf_counter() - t0)


def _fit_meter_out(p: PVG32Params, shape, pts, steady, kind: str = "overlap"):
    """(Pb shift [Pa], meter-out parameter): least squares of the training Pb to the model's
    P_b - shift + (P_b - P_T) ((A_H / A_out)^2 - 1) at the model's steady states: P_b - P_T is
    the meter-out drop, which return edges of their own multiply by the square of the area
    ratio; the shift is the return line's. ``kind`` "overlap": A_out = A_H(u - overlap),
    returns the overlap [m]; "ratio": A_out = A_H(u) (r0 + r1 u), returns (r0, r1 [1/m])."""
    u = np.array([abs(steady[s.name]["x_m"]) for s in pts])
    x = u
    drop = np.array([0.0 if _is_neutral(s) else
                     steady[s.name]["Pb"] - p.rig.pb_sensor_offset - steady[s.name]["P_T"]
                     for s in pts])
    pb = np.array([steady[s.name]["Pb"] for s in pts])
    meas = np.array([s.measured.Pb for s in pts])
    a = _area(p, shape, x)
    u_min = float(min(v - p.main_spool.dead_band for v, s in zip(u, pts) if not _is_neutral(s)))

    def resid(z):
        shift, d = z[0] * bar(1.0), z[1] * 1e-3
        ratio = (a / np.maximum(_area(p, shape, x - d), 1e-12)) ** 2
        return (pb - shift + drop * (ratio - 1.0) - meas) / bar(1.0)

    if kind == "ratio":
        uu = (u - p.main_spool.dead_band) * 1e3               # [mm]

        def resid_ratio(z):
            ratio = np.maximum(z[1] + z[2] * uu, 0.05) ** -2
            return (pb - z[0] * bar(1.0) + drop * (ratio - 1.0) - meas) / bar(1.0)
        # the shift and r0 are nearly collinear: start from both ends, keep the best
        sol = min((least_squares(resid_ratio, z0, bounds=([-20.0, 0.3, -1.0], [20.0, 3.0, 1.0]))
                   for z0 in ([0.0, 1.0, 0.0], [-3.0, 1.2, 0.5])), key=lambda r: r.cost)
        return float(sol.x[0]) * bar(1.0), (float(sol.x[1]), float(sol.x[2]) * 1e3)
    hi = max(0.8 * u_min * 1e3, 1e-6)
    sol = least_squares(resid, [0.0, min(0.02, hi / 2)], bounds=([-20.0, 0.0], [20.0, hi]))
    return float(sol.x[0]) * bar(1.0), float(sol.x[1]) * 1e-3


# ------------------------------------------------------------------------------ cross-validation
def _voltage_key(s: Scenario) -> str:
    return f"U = {s.U_input:g} V"


def _load_key(s: Scenario) -> str:
    if s.kind == "voltage_sweep":
        return "sweep (L3 large, L2 closed)"
    return f"L1 {s.orifice_L1}, L3 {s.orifice_L3}"


GROUPINGS = {"voltage": _voltage_key, "load": _load_key}


def fold_keys(groupings=("voltage", "load")) -> list[str]:
    """The names of the folds of :func:`cross_validate` (``"U = 4.6 V"``, ...)."""
    return list(dict.fromkeys(GROUPINGS[g](s) for g in groupings for s in all_scenarios()))


@dataclass
class CrossValidation:
    """Held-out predictions of every fold, as records, plus the cost."""

    records: list[dict]
    folds: list[dict]
    wall_time: float
    workers: int


def _fold(args):
    grouping, key, train_names, test_names, base, options = args
    train = [get_scenario(n) for n in train_names]
    test = [get_scenario(n) for n in test_names]
    loads_from = test if grouping == "load" else ()
    try:
        ident = identify(train, base, loads_from=loads_from, **options)
        pred = steady_values(ident.params, test, sweep_load=ident.sweep_load)
    except (PvgraphError, ValueError) as exc:        # a failed fold is recorded, not raised
        message = f"{type(exc).__name__}: {str(exc).splitlines()[0]}"
        ident = Identification(base, {"error": message})
        pred = {s.name: {"error": message} for s in test}
    records = []
    for s in test:
        values = pred[s.name]
        for q in QUANTITIES:
            conv = to_lpm if q.startswith("Q") else to_bar
            measured = conv(getattr(s.measured, q))
            simulated = None if "error" in values else conv(values[q])
            records.append({
                "grouping": grouping, "fold": key, "scenario": s.name, "quantity": q,
                "unit": "L/min" if q.startswith("Q") else "bar",
                "measured": round(measured, 4),
                "simulated": None if simulated is None else round(simulated, 4),
                "error": None if simulated is None else round(simulated - measured, 4),
                "role": role(s, q, ident.fitted)})
    fold = {"grouping": grouping, "fold": key, "held_out": test_names,
            "sources": ident.sources, "identify_wall_time": round(ident.wall_time, 2)}
    return records, fold


def cross_validate(groupings=("voltage", "load"), base: PVG32Params | None = None, *,
                   workers: int = 2, progress=None,
                   load_law: str = "shared", measurement: bool = True,
                   meter_out: str | None = None,
                   folds: list[str] | None = None) -> CrossValidation:
    """Leave one group out per grouping; identify on the rest; predict the group's steady
    states. ``load_law``, ``measurement``, ``meter_out`` as in :func:`identify`; ``folds``: only the folds
    whose key is listed (e.g. ``["U = 4.6 V"]``), for a quick look at one group."""
    base = base or report_tuned()
    scenarios = all_scenarios()
    jobs = []
    for g in groupings:
        if g not in GROUPINGS:
            raise PvgraphError(f"unknown grouping {g!r}; choose from {sorted(GROUPINGS)}")
        keyf = GROUPINGS[g]
        keys = list(dict.fromkeys(keyf(s) for s in scenarios))
        for key in keys:
            test = [s.name for s in scenarios if keyf(s) == key]
            train = [s.name for s in scenarios if keyf(s) != key]
            if folds is not None and key not in folds:
                continue
            jobs.append((g, key, train, test, base,
                         {"load_law": load_law, "measurement": measurement,
                          "meter_out": meter_out}))
    t0 = time.perf_counter()
    records, folds = [], []
    workers = max(1, min(workers, len(jobs), MAX_PROCESS_WORKERS))   # no idle processes
    if workers > 1:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            for job, (rec, fold) in zip(jobs, pool.map(_fold, jobs)):
                records += rec
                folds.append(fold)
                if progress:
                    progress(f"{job[0]}: {job[1]}")
    else:
        for job in jobs:
            rec, fold = _fold(job)
            records += rec
            folds.append(fold)
            if progress:
                progress(f"{job[0]}: {job[1]}")
    return CrossValidation(records, folds, time.perf_counter() - t0, workers)


def judge(records: list[dict], grouping: str | None = None, roles=("held-out",)) -> dict:
    """The acceptance targets over ``records`` of the given roles (absolute tolerances).

    Returns ``{target: (passed, total, [(scenario, worst error, ok), ...])}``: flow within
    1 L/min at the non-neutral points; Pf, Pm, Pb all within 2 bar per step test and per
    non-neutral sweep point. A point counts when its judged quantity has one of ``roles``.
    """
    recs = [r for r in records if grouping is None or r.get("grouping") == grouping]
    by_scn: dict[str, dict] = {}
    for r in recs:
        by_scn.setdefault(r["scenario"], {})[r["quantity"]] = r
    flow, steps, sweep = [], [], []
    for name, qs in by_scn.items():
        s = get_scenario(name)
        if _is_neutral(s):
            continue
        rq = qs.get("Q_total")
        if rq and rq["error"] is not None and rq["role"] in roles:
            err = abs(rq["error"])
            flow.append((name, err, err <= to_lpm(FLOW_TOL) + 1e-9))
        ps = [qs[q] for q in ("Pf", "Pm", "Pb") if q in qs]
        if ps and all(r["role"] in roles for r in ps) and all(r["error"] is not None
                                                              for r in ps):
            worst = max(abs(r["error"]) for r in ps)
            (steps if s.kind == "solenoid_step" else sweep).append(
                (name, worst, worst <= to_bar(PRESSURE_TOL) + 1e-9))
    return {
        "flow within 1 L/min (non-neutral points)": _count(flow),
        "Pf, Pm, Pb within 2 bar (step tests)": _count(steps),
        "Pf, Pm, Pb within 2 bar (non-neutral sweep points)": _count(sweep),
    }


def _count(rows):
    return sum(ok for *_, ok in rows), len(rows), rows


#: The settling checks of :func:`pvgraph.circuits.validation.targets` (model checks):
SETTLED_STEP = "settled within 0.5 s of the solenoid step (step tests)"
STEADY_AT_END = "steady at the end of the 8 s run from rest (no step: Pf flat over the last 1 s)"

#: Share of the points a target asks to pass: flow within 1 L/min at 15 of the 17 non-neutral
#: points, Pf, Pm and Pb within 2 bar at 10 of the 12 step tests and at every non-neutral sweep
#: point, settled within 0.5 s of the step in 7 of the 8 step tests (one miss allowed). Labels
#: not listed ask for all.
HELD_OUT_TARGETS = {"flow within 1 L/min (non-neutral points)": 15 / 17,
                    "Pf, Pm, Pb within 2 bar (step tests)": 10 / 12,
                    SETTLED_STEP: 7 / 8}


def held_out_target(label: str, total: int) -> int:
    """How many of ``total`` held-out points the target for ``label`` asks to pass."""
    return math.ceil(HELD_OUT_TARGETS.get(label, 1.0) * total - 1e-9)


def shown_against(value: float, tol: float) -> str:
    """``value`` with 2 decimals, or as many more as it takes for the printed number to fall on
    the same side of the tolerance ``tol`` as the value (1.0019 against 1.0 prints 1.002, not
    1.00)."""
    for digits in range(2, 10):
        text = f"{value:.{digits}f}"
        if (float(text) > tol) == (value > tol):
            return text
    return repr(value)


def format_cross_validation(cv: CrossValidation) -> str:
    """Per grouping: one row per held-out scenario (errors and roles), then the targets."""
    lines = []
    for g in dict.fromkeys(r["grouping"] for r in cv.records):
        recs = [r for r in cv.records if r["grouping"] == g]
        lines.append(f"leave one {g} group out: predicted - measured (role: h held-out, "
                     f"f fit, r repeat of a fit, t trivial)")
        head = (f"{'scenario':9s} {'fold':30s} | {'Q_total':>9s} {'Q_branch':>9s} | "
                f"{'Pf':>8s} {'Pm':>8s} {'Pb':>8s}")
        lines += [head, "-" * len(head)]
        by_scn: dict[str, dict] = {}
        for r in recs:
            by_scn.setdefault(r["scenario"], {})[r["quantity"]] = r
        for name, qs in by_scn.items():
            cells = []
            for q in QUANTITIES:
                r = qs[q]
                code = ROLE_CODES[r["role"]]
                tol = to_lpm(FLOW_TOL) if q.startswith("Q") else to_bar(PRESSURE_TOL)
                cells.append("  failed " if r["error"] is None else
                             f"{'-' if r['error'] < 0 else '+'}"
                             f"{shown_against(abs(r['error']), tol)}{code}")
            fold = qs["Q_total"]["fold"]
            lines.append(f"{name:9s} {fold[:30]:30s} | {cells[0]:>9s} {cells[1]:>9s} | "
                         f"{cells[2]:>8s} {cells[3]:>8s} {cells[4]:>8s}")
        for label, (ok, total, rows) in judge(cv.records, g).items():
            if not total:
                why = ("the held-out configuration's load law is its own tests' Q/dp"
                       if g == "load" else "no such point in the folds run")
                lines.append(f"  n/a   held-out {label}: none held out ({why})")
                continue
            name, worst, _ = max(rows, key=lambda row: row[1])
            tol = to_lpm(FLOW_TOL) if label.startswith("flow") else to_bar(PRESSURE_TOL)
            need = held_out_target(label, total)
            verdict = "PASS" if ok >= need else "miss"
            aim = "" if need == total else f"; target >= {need} of {total}, aim {total}"
            lines.append(f"  {verdict}  held-out {label}: {ok}/{total} (worst "
                         f"{shown_against(worst, tol)} at {name}{aim})")
        lines.append("")
    lines.append(f"{len(cv.folds)} fold{'s' if len(cv.folds) != 1 else ''}, {cv.wall_time:.1f} s wall on {cv.workers} "
                 f"process(es) (steady states)")
    return "\n".join(lines)
